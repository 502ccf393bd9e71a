//! Synthetic workloads for the partitioning experiments: N small triangles
//! (item = centroid, bounding box, 72 bytes of vertices), spread over the
//! ranks by id so that the first partitioning has real work to do.

use crate::{Aabb, Item, LocalItems};

/// How the items are placed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Workload {
    /// Uniform in the unit cube.
    Uniform,
    /// Eight Gaussian blobs (sigma 0.05) in the unit cube.
    Blobs,
    /// Items falling through a funnel onto a floor: the distribution changes
    /// with the step, from a uniform cloud above to a pile at the outlet.
    Hopper,
    /// A slab a little taller than wide that spreads until it is a little
    /// wider than tall (a column collapsing, in small): the items barely
    /// move, but the longest axis turns from z to x at time 0.02.
    Spreading,
    /// A column twice as tall as wide settling towards its floor: every
    /// height shrinks by one factor, a tenth over the run, so the items keep
    /// their order along the column while they cross any fixed height.
    Settling,
}

impl Workload {
    pub const ALL: [Workload; 5] = [
        Workload::Uniform,
        Workload::Blobs,
        Workload::Hopper,
        Workload::Spreading,
        Workload::Settling,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Workload::Uniform => "uniform",
            Workload::Blobs => "blobs",
            Workload::Hopper => "hopper",
            Workload::Spreading => "spreading",
            Workload::Settling => "settling",
        }
    }
}

impl std::str::FromStr for Workload {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Workload::ALL
            .into_iter()
            .find(|w| w.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Workload::ALL.iter().map(|w| w.name()).collect();
                format!("unknown workload `{s}` ({})", names.join(", "))
            })
    }
}

/// Bytes of a triangle's vertices, the payload that migrates with it.
pub const TRIANGLE_BYTES: u32 = 72;

/// A reproducible uniform number in [0, 1) from an id and a stream.
fn unit(id: u64, stream: u64) -> f64 {
    // splitmix64
    let mut z = id.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

fn gaussian(id: u64, stream: u64) -> f64 {
    let u1 = unit(id, stream).max(1e-300);
    let u2 = unit(id, stream + 1);
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

impl Workload {
    /// Centre of item `id` at time fraction `t` in [0, 1] of the run.
    pub fn centre(self, id: u64, t: f64) -> [f64; 3] {
        match self {
            Workload::Uniform => [unit(id, 1), unit(id, 2), unit(id, 3)],
            Workload::Blobs => {
                let blob = (unit(id, 4) * 8.0) as u64;
                let c = [
                    0.15 + 0.7 * unit(blob, 10),
                    0.15 + 0.7 * unit(blob, 11),
                    0.15 + 0.7 * unit(blob, 12),
                ];
                [0, 1, 2].map(|k| (c[k] + 0.05 * gaussian(id, 20 + 2 * k as u64)).clamp(0.0, 1.0))
            }
            Workload::Hopper => {
                let (x0, y0, z0) = (unit(id, 1), unit(id, 2), 1.0 + unit(id, 3));
                // Fall 1.8 over the run; below z = 1 the funnel draws items to its axis.
                let floor = 0.3 * unit(id, 5);
                let z = (z0 - 1.8 * t).max(floor);
                let squeeze = z.clamp(0.15, 1.0);
                [0.5 + (x0 - 0.5) * squeeze, 0.5 + (y0 - 0.5) * squeeze, z]
            }
            Workload::Spreading => [
                unit(id, 1) * (0.99 + t),
                0.5 * unit(id, 2),
                unit(id, 3) * (1.01 - t),
            ],
            Workload::Settling => [
                unit(id, 1),
                unit(id, 2),
                2.0 * unit(id, 3) * (1.0 - 0.1 * t),
            ],
        }
    }
}

/// Parameters of a generated item set.
#[derive(Debug, Clone, Copy)]
pub struct Spec {
    pub workload: Workload,
    /// Items over all ranks.
    pub items: u64,
    /// Edge length of the triangles.
    pub size: f64,
}

impl Spec {
    pub fn new(workload: Workload, items: u64) -> Self {
        // A tenth of the mean spacing of uniformly spread items, so that even the
        // densest state (blobs, the hopper's pile: about a third of that
        // spacing) has triangles that do not interpenetrate much.
        let size = 0.1 / (items.max(1) as f64).cbrt();
        Spec {
            workload,
            items,
            size,
        }
    }

    /// Ids this rank generates at the start: a contiguous block.
    pub fn ids_of(&self, rank: i32, ranks: i32) -> std::ops::Range<u64> {
        let n = self.items;
        let (r, p) = (rank as u64, ranks as u64);
        (n * r / p)..(n * (r + 1) / p)
    }

    /// The item `id` at time fraction `t`.
    pub fn item(&self, id: u64, t: f64) -> Item {
        let c = self.workload.centre(id, t);
        // A small triangle around the centre, oriented by the id.
        let a = 2.0 * std::f64::consts::PI * unit(id, 7);
        let h = 0.5 * self.size;
        let v = [
            [c[0] + h * a.cos(), c[1] + h * a.sin(), c[2]],
            [c[0] - h * a.sin(), c[1] + h * a.cos(), c[2] + h * 0.5],
            [c[0] - h * a.cos(), c[1] - h * a.sin(), c[2] - h * 0.5],
        ];
        let mut bbox = Aabb::EMPTY;
        for p in v {
            bbox.grow(p);
        }
        Item {
            id,
            point: c,
            weight: 1.0,
            bbox,
            payload_bytes: TRIANGLE_BYTES,
        }
    }

    /// This rank's initial items.
    pub fn initial(&self, rank: i32, ranks: i32) -> LocalItems {
        LocalItems::with_id_payloads(
            self.ids_of(rank, ranks)
                .map(|id| self.item(id, 0.0))
                .collect(),
        )
    }

    /// Moves the items to time fraction `t` (they keep their owners until repartitioned).
    pub fn advance(&self, local: &mut LocalItems, t: f64) {
        for it in &mut local.items {
            *it = self.item(it.id, t);
        }
    }
}
