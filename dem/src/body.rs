//! Rigid bodies: a shared mesh in body coordinates, and the state that moves it.

pub use crate::drive::{Drive, Profile};
use glam::{DMat3, DQuat, DVec3};

/// A rigid particle or a static obstacle.
#[derive(Debug, Clone)]
pub struct Body {
    /// Index of the shape in `World::shapes` (vertices relative to the centre of mass).
    pub shape: usize,
    pub material: usize,
    /// Position of the centre of mass.
    pub x: DVec3,
    pub q: DQuat,
    pub v: DVec3,
    /// Angular momentum in world axes: conserved exactly by the integrator when no torque acts.
    pub l: DVec3,
    /// 0 for a static obstacle.
    pub inv_mass: f64,
    pub mass: f64,
    /// Inverse inertia tensor in body axes (zero for an obstacle).
    pub inv_inertia_body: DMat3,
    pub inertia_body: DMat3,
    /// An obstacle's prescribed motion (`None`: it stands still, or the body
    /// is a particle, moved by its forces).
    pub drive: Option<Box<Drive>>,
    /// A particle taken out of the run by an outflow: it no longer moves,
    /// touches nothing and is acted on by nothing; its state stays as it was
    /// when it left (which the energy books and the output read).
    pub removed: bool,
    /// A particle waiting to be inserted (an insertion): until then it does
    /// not move, touches nothing and is acted on by nothing, like a removed
    /// one; its state is where and how it will enter, but for its position.
    pub pending: bool,
}

impl Body {
    /// An obstacle: no force moves it (it stands still or is driven).
    pub fn is_static(&self) -> bool {
        self.inv_mass == 0.0
    }

    /// An obstacle that never moves.
    pub fn is_fixed(&self) -> bool {
        self.is_static() && self.drive.is_none()
    }

    /// Whether the body takes part in contacts: false for an obstacle
    /// removed by its drive (as of the time it was last placed), and for a
    /// particle an outflow took out.
    pub fn is_present(&self) -> bool {
        !self.is_out() && self.drive.as_ref().is_none_or(|d| d.present())
    }

    /// A particle out of the run: not yet inserted, or taken out.
    pub fn is_out(&self) -> bool {
        self.removed || self.pending
    }

    /// Whether every state variable (position, orientation, velocity,
    /// angular momentum) is finite.
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.q.is_finite() && self.v.is_finite() && self.l.is_finite()
    }

    /// A driven obstacle placed where its drive puts it at time `t`.
    pub fn follow_drive(&mut self, t: f64) {
        if let Some(d) = &mut self.drive {
            (self.x, self.q, self.v) = d.place(t);
        }
    }

    /// Rotation matrix body -> world.
    pub fn rotation(&self) -> DMat3 {
        DMat3::from_quat(self.q)
    }

    /// Angular velocity in world axes: ω = R I⁻¹ Rᵀ L (a driven obstacle's
    /// prescribed one).
    pub fn omega(&self) -> DVec3 {
        match &self.drive {
            Some(d) => d.omega(),
            None => omega_of(self.q, self.inv_inertia_body, self.l),
        }
    }

    /// Velocity of the body's material point at world position `p`.
    pub fn velocity_at(&self, p: DVec3) -> DVec3 {
        self.v + self.omega().cross(p - self.x)
    }

    pub fn kinetic_energy(&self) -> f64 {
        if self.is_static() {
            return 0.0;
        }
        0.5 * self.mass * self.v.length_squared() + 0.5 * self.l.dot(self.omega())
    }

    /// World-space vertex of the body's shape.
    pub fn to_world(&self, local: DVec3) -> DVec3 {
        self.x + self.q * local
    }
}

/// ω = R I⁻¹ Rᵀ L for orientation q.
#[inline]
pub fn omega_of(q: DQuat, inv_inertia_body: DMat3, l: DVec3) -> DVec3 {
    q * (inv_inertia_body * (q.inverse() * l))
}
