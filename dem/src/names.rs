//! Enums chosen by name (in scene files and on command lines), each from one
//! table of its values and their names.

/// Gives an enum its table of names, `ALL: [(value, name)]`, and reads
/// everything else from it: `name()`, `FromStr` (whose error lists the
/// names), and with the crate's `clap` feature, `clap::ValueEnum`.
///
/// ```
/// #[derive(Debug, Clone, Copy, PartialEq, Eq)]
/// enum Colour { Red, Blue }
/// dem::named_enum!(Colour, "colour", [(Red, "red"), (Blue, "blue")]);
/// assert_eq!(Colour::Red.name(), "red");
/// assert_eq!("blue".parse::<Colour>(), Ok(Colour::Blue));
/// assert_eq!("green".parse::<Colour>().unwrap_err(), "unknown colour `green` (red, blue)");
/// ```
#[macro_export]
macro_rules! named_enum {
    ($ty:ident, $what:literal, [$(($variant:ident, $name:literal)),+ $(,)?]) => {
        impl $ty {
            /// Every value, with its name: the one list the command line,
            /// the scene files and the studies read.
            pub const ALL: &'static [($ty, &'static str)] = &[$(($ty::$variant, $name)),+];

            pub fn name(self) -> &'static str {
                Self::ALL
                    .iter()
                    .find(|(v, _)| *v == self)
                    .map(|(_, n)| *n)
                    .expect("every value is in its table")
            }
        }

        impl std::str::FromStr for $ty {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                match Self::ALL.iter().find(|(_, n)| *n == s) {
                    Some((v, _)) => Ok(*v),
                    None => {
                        let names: Vec<&str> = Self::ALL.iter().map(|(_, n)| *n).collect();
                        Err(format!("unknown {} `{s}` ({})", $what, names.join(", ")))
                    }
                }
            }
        }

        #[cfg(feature = "clap")]
        impl clap::ValueEnum for $ty {
            fn value_variants<'a>() -> &'a [Self] {
                &[$($ty::$variant),+]
            }

            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                Some(clap::builder::PossibleValue::new(self.name()))
            }
        }
    };
}

/// Reads a named value (see [`named_enum!`]) from a scene's string, for
/// `#[serde(deserialize_with = ...)]`: an unknown name is refused with the
/// list of names.
pub(crate) fn by_name<'de, D, T>(d: D) -> Result<T, D::Error>
where
    D: serde::Deserializer<'de>,
    T: std::str::FromStr<Err = String>,
{
    let s = <String as serde::Deserialize>::deserialize(d)?;
    s.parse().map_err(serde::de::Error::custom)
}
