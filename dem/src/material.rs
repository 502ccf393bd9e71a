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
}
