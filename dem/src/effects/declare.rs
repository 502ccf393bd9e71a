//! How a scene declares effects. Each effect is one unit: a parameter type
//! that names the effect, reads its own table of the scene's `[effects]`,
//! lists the material parameters it needs and the effects it builds on, and
//! builds its part of the step pipeline ([`Declare`]). [`KINDS`] registers
//! each in one line, as LAMMPS registers a fix; nothing else matches effects
//! by name.

use super::{Effect, KINDS};
use crate::distance::Options;
use crate::material::Material;
use crate::world::World;
use serde::de::DeserializeOwned;
use std::any::Any;
use std::fmt::Debug;

/// What an effect unit declares. The type itself holds the effect's
/// parameters as the scene writes them (`damping = { linear = 0.5 }`).
pub trait Declare: Debug + Clone + PartialEq + Send + Sync + DeserializeOwned + 'static {
    /// The effect's key in `[effects]`.
    const NAME: &'static str;
    /// Effects that must be declared with this one.
    const NEEDS: &'static [&'static str] = &[];
    /// Parameters every material must set when the effect is declared (and
    /// none may set when it is not).
    const MATERIAL_PARAMS: &'static [MaterialParam] = &[];
    /// Checks the parameters beyond their types (the cause, if refused).
    fn check(&self) -> Result<(), String> {
        Ok(())
    }
    /// The effect's unit of the step pipeline (`None` for an effect that
    /// changes how the step integrates instead of adding forces).
    fn build(&self, setting: &Setting) -> Option<Box<dyn Effect>>;
}

/// What an effect is built from: the world it acts on, the distance kernel's
/// options and the other declared effects; not the scene, which the effect
/// layer does not know.
pub struct Setting<'a> {
    pub world: &'a World,
    pub kernel: Options,
    pub effects: &'a Effects,
}

/// A material parameter an effect needs.
pub struct MaterialParam {
    pub name: &'static str,
    pub get: fn(&Material) -> Option<f64>,
    /// What a value must be, as the refusal says it, and the test.
    pub must_be: &'static str,
    pub accepts: fn(f64) -> bool,
}

/// One registered effect: what [`Declare`] says of it, without its type.
pub struct Kind {
    pub name: &'static str,
    pub needs: &'static [&'static str],
    pub material_params: &'static [MaterialParam],
    read: fn(toml::Value) -> Result<Box<dyn Declared>, String>,
}

/// The registered effect `T`.
pub const fn kind<T: Declare>() -> Kind {
    Kind {
        name: T::NAME,
        needs: T::NEEDS,
        material_params: T::MATERIAL_PARAMS,
        read: read::<T>,
    }
}

fn read<T: Declare>(table: toml::Value) -> Result<Box<dyn Declared>, String> {
    let params: T = table
        .try_into()
        .map_err(|e: toml::de::Error| format!("effects.{}: {}", T::NAME, e.message().trim_end()))?;
    params
        .check()
        .map_err(|cause| format!("effects.{}: {cause}", T::NAME))?;
    Ok(Box::new(params))
}

/// A declared effect's parameters, whatever the effect.
pub trait Declared: Debug + Send + Sync {
    fn name(&self) -> &'static str;
    fn build(&self, setting: &Setting) -> Option<Box<dyn Effect>>;
    fn as_any(&self) -> &dyn Any;
    fn clone_box(&self) -> Box<dyn Declared>;
    fn same_as(&self, other: &dyn Declared) -> bool;
}

impl<T: Declare> Declared for T {
    fn name(&self) -> &'static str {
        T::NAME
    }
    fn build(&self, setting: &Setting) -> Option<Box<dyn Effect>> {
        Declare::build(self, setting)
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn clone_box(&self) -> Box<dyn Declared> {
        Box::new(self.clone())
    }
    fn same_as(&self, other: &dyn Declared) -> bool {
        other.as_any().downcast_ref::<T>() == Some(self)
    }
}

/// The effects a scene declared, with their parameters, in the order of
/// [`KINDS`] (the order of the step pipeline).
#[derive(Debug, Default)]
pub struct Effects(Vec<Box<dyn Declared>>);

impl Clone for Effects {
    fn clone(&self) -> Effects {
        Effects(self.0.iter().map(|d| d.clone_box()).collect())
    }
}

impl PartialEq for Effects {
    fn eq(&self, o: &Effects) -> bool {
        self.0.len() == o.0.len() && self.0.iter().zip(&o.0).all(|(a, b)| a.same_as(&**b))
    }
}

impl Effects {
    /// Reads `[effects]`: each entry by its registered kind, then checks
    /// that what each needs is declared. An error names the key at fault.
    pub fn read(
        entries: impl IntoIterator<Item = (String, toml::Value)>,
    ) -> Result<Effects, (String, String)> {
        let mut declared: Vec<(usize, Box<dyn Declared>)> = Vec::new();
        for (key, value) in entries {
            let Some(k) = KINDS.iter().position(|k| k.name == key) else {
                let known: Vec<_> = KINDS.iter().map(|k| k.name).collect();
                let cause = format!(
                    "unknown effect `{key}`; the effects are {}",
                    known.join(", ")
                );
                return Err((key, cause));
            };
            let params = (KINDS[k].read)(value).map_err(|cause| (key.clone(), cause))?;
            declared.push((k, params));
        }
        declared.sort_by_key(|d| d.0);
        let effects = Effects(declared.into_iter().map(|d| d.1).collect());
        for name in effects.names() {
            for need in kind_of(name).needs {
                if !effects.names().contains(need) {
                    let cause = format!("the {name} effect needs the {need} effect");
                    return Err((name.to_string(), cause));
                }
            }
        }
        Ok(effects)
    }

    /// The declared effects' names, in pipeline order.
    pub fn names(&self) -> Vec<&'static str> {
        self.0.iter().map(|d| d.name()).collect()
    }

    /// The declared effects' parameters, in pipeline order.
    pub fn iter(&self) -> impl Iterator<Item = &dyn Declared> {
        self.0.iter().map(|d| &**d)
    }

    /// The parameters of effect `T`, if declared.
    pub fn get<T: Declare>(&self) -> Option<&T> {
        self.0.iter().find_map(|d| d.as_any().downcast_ref::<T>())
    }

    pub fn has<T: Declare>(&self) -> bool {
        self.get::<T>().is_some()
    }

    /// Declares effect `T` with `params` (replacing it if declared).
    pub fn set<T: Declare>(&mut self, params: T) {
        self.remove::<T>();
        let at = |name| KINDS.iter().position(|k| k.name == name);
        let pos = self.0.iter().position(|d| at(d.name()) > at(T::NAME));
        self.0.insert(pos.unwrap_or(self.0.len()), Box::new(params));
    }

    /// Leaves effect `T` out.
    pub fn remove<T: Declare>(&mut self) {
        self.0.retain(|d| d.name() != T::NAME);
    }

    /// The material parameters the declared effects need, with the effect
    /// that needs each.
    pub fn material_params(
        &self,
    ) -> impl Iterator<Item = (&'static str, &'static MaterialParam)> + '_ {
        self.names()
            .into_iter()
            .flat_map(|n| kind_of(n).material_params.iter().map(move |p| (n, p)))
    }
}

/// The registered kind named `name`.
pub fn kind_of(name: &str) -> &'static Kind {
    KINDS
        .iter()
        .find(|k| k.name == name)
        .expect("declared effects are registered")
}
