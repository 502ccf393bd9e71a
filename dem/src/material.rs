//! Materials: density and the parameters of the effects that use them.

/// A material. Parameters of effects are optional here; the scene checks that
/// every parameter given belongs to a declared effect, and that every declared
/// effect finds the parameters it needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    pub name: String,
    pub density: f64,
    /// Normal contact stiffness (N/m): `contact` effect.
    pub stiffness: Option<f64>,
    /// Coefficient of restitution in (0, 1]: `contact` effect.
    pub restitution: Option<f64>,
    /// Contact halo (m): `contact` effect.
    pub halo: Option<f64>,
    /// Coulomb friction coefficient: `friction` effect.
    pub friction: Option<f64>,
}

/// Damping ratio giving restitution `e` for a linear spring-dashpot:
/// ζ = −ln e / √(π² + ln² e).
pub fn damping_ratio(e: f64) -> f64 {
    let l = e.ln();
    -l / (std::f64::consts::PI.powi(2) + l * l).sqrt()
}

/// Two normal springs in series, k_a k_b / (k_a + k_b): the stiffness of
/// the contact between materials of stiffnesses `ka` and `kb`.
#[inline]
pub fn in_series(ka: f64, kb: f64) -> f64 {
    ka * kb / (ka + kb)
}

/// The constants of the contact laws between two materials.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairLaw {
    /// The two normal springs in series: k_a k_b / (k_a + k_b).
    pub stiffness: f64,
    /// ζ for the mean restitution of the two, (e_a + e_b) / 2.
    pub damping_ratio: f64,
    /// Geometric mean of the friction coefficients, √(μ_a μ_b).
    pub friction: f64,
}

/// [`PairLaw`] for every pair of materials, computed once: the step needs
/// them per contact, where a logarithm and square roots would cost more than
/// the force itself. Missing parameters count as 0, as in `World::per_body`.
#[derive(Debug, Clone, Default)]
pub struct MaterialPairs {
    n: usize,
    laws: Vec<PairLaw>,
}

impl MaterialPairs {
    pub fn new(materials: &[Material]) -> MaterialPairs {
        let n = materials.len();
        let mut laws = Vec::with_capacity(n * n);
        for a in materials {
            for b in materials {
                let (ka, kb) = (a.stiffness.unwrap_or(0.0), b.stiffness.unwrap_or(0.0));
                let (ea, eb) = (a.restitution.unwrap_or(0.0), b.restitution.unwrap_or(0.0));
                let (ma, mb) = (a.friction.unwrap_or(0.0), b.friction.unwrap_or(0.0));
                laws.push(PairLaw {
                    stiffness: in_series(ka, kb),
                    damping_ratio: damping_ratio(0.5 * (ea + eb)),
                    friction: (ma * mb).sqrt(),
                });
            }
        }
        MaterialPairs { n, laws }
    }

    /// The law between materials `a` and `b`.
    #[inline]
    pub fn get(&self, a: usize, b: usize) -> &PairLaw {
        &self.laws[a * self.n + b]
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn damping_ratio_limits() {
        assert_eq!(super::damping_ratio(1.0), 0.0);
        let z = super::damping_ratio(0.5);
        // e = exp(−ζπ/√(1−ζ²)) inverts it.
        let e = (-z * std::f64::consts::PI / (1.0 - z * z).sqrt()).exp();
        assert!((e - 0.5).abs() < 1e-12);
    }

    #[test]
    fn pair_laws_are_symmetric_and_combine_as_documented() {
        let m = |k: f64, e: f64, mu: f64| super::Material {
            name: String::new(),
            density: 1.0,
            stiffness: Some(k),
            restitution: Some(e),
            halo: None,
            friction: Some(mu),
        };
        let mats = [m(1e4, 0.4, 0.3), m(3e4, 0.8, 0.12)];
        let t = super::MaterialPairs::new(&mats);
        assert_eq!(t.get(0, 1), t.get(1, 0));
        let l = t.get(0, 1);
        // 1/k = 1/k_a + 1/k_b; e the mean; μ the geometric mean.
        assert!((1.0 / l.stiffness - (1.0 / 1e4 + 1.0 / 3e4)).abs() < 1e-15);
        assert!((l.damping_ratio - super::damping_ratio(0.6)).abs() < 1e-15);
        assert!((l.friction - 0.036f64.sqrt()).abs() < 1e-15);
        assert_eq!(t.get(1, 1).stiffness, 1.5e4);
    }
}
