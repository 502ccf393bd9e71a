//! A small software renderer for pictures of a run: triangles with a depth
//! buffer and flat shading under an orthographic camera, translucent
//! triangles blended over them, and lines drawn on top.
//!
//! Why not ParaView: a picture should not need a 300 MB install, and a
//! granular scene is a few thousand flat-shaded triangles, which a
//! z-buffer draws in milliseconds. ParaView remains the tool for
//! exploring a run (`run.xmf`, docs/output.md).

use glam::DVec3;

/// An orthographic camera looking along `forward`, z up on the picture.
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    /// Picture coordinates of the scene's point 0: x, y offset and scale.
    offset: (f64, f64),
    scale: f64,
}

impl Camera {
    /// A camera looking along `forward` that fits `points` into a picture
    /// of `size` pixels with a margin of a twentieth.
    pub fn fitting(forward: DVec3, points: &[DVec3], size: (u32, u32)) -> Camera {
        let forward = forward.normalize();
        let up_hint = if forward.cross(DVec3::Z).length() < 1e-6 {
            DVec3::Y
        } else {
            DVec3::Z
        };
        let right = forward.cross(up_hint).normalize();
        let up = right.cross(forward);
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for p in points {
            let (x, y) = (p.dot(right), p.dot(up));
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
        let (w, h) = (f64::from(size.0), f64::from(size.1));
        let span = ((hi.0 - lo.0) / w)
            .max((hi.1 - lo.1) / h)
            .max(f64::MIN_POSITIVE);
        let scale = 0.9 / span;
        let centre = (0.5 * (lo.0 + hi.0), 0.5 * (lo.1 + hi.1));
        Camera {
            right,
            up,
            forward,
            offset: (0.5 * w - scale * centre.0, 0.5 * h + scale * centre.1),
            scale,
        }
    }

    /// Picture x, y (pixels, y down) and depth (larger: further).
    pub fn project(&self, p: DVec3) -> (f64, f64, f64) {
        (
            self.offset.0 + self.scale * p.dot(self.right),
            self.offset.1 - self.scale * p.dot(self.up),
            p.dot(self.forward),
        )
    }

    pub fn forward(&self) -> DVec3 {
        self.forward
    }
}

/// An RGB picture with a depth per pixel.
pub struct Picture {
    pub size: (u32, u32),
    pub rgb: Vec<[f64; 3]>,
    depth: Vec<f64>,
}

impl Picture {
    pub fn new(size: (u32, u32), background: [f64; 3]) -> Picture {
        let n = (size.0 * size.1) as usize;
        Picture {
            size,
            rgb: vec![background; n],
            depth: vec![f64::INFINITY; n],
        }
    }

    /// A triangle of colour `colour`, shaded by how squarely it faces the
    /// camera; with `alpha` < 1 blended over what is nearer or behind,
    /// leaving the depths as they were.
    pub fn triangle(&mut self, cam: &Camera, t: [DVec3; 3], colour: [f64; 3], alpha: f64) {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        let facing = n.normalize_or_zero().dot(cam.forward()).abs();
        let shade = 0.35 + 0.65 * facing;
        let c = colour.map(|x| x * shade);
        let p = t.map(|v| cam.project(v));
        let area = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
        if area.abs() < 1e-12 {
            return;
        }
        let (w, h) = (self.size.0 as i64, self.size.1 as i64);
        let (x0, x1) = pixel_span([p[0].0, p[1].0, p[2].0], w);
        let (y0, y1) = pixel_span([p[0].1, p[1].1, p[2].1], h);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let edge = |a: (f64, f64, f64), b: (f64, f64, f64)| {
                    ((b.0 - a.0) * (py - a.1) - (px - a.0) * (b.1 - a.1)) / area
                };
                let (l0, l1, l2) = (edge(p[1], p[2]), edge(p[2], p[0]), edge(p[0], p[1]));
                if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
                    continue;
                }
                let z = l0 * p[0].2 + l1 * p[1].2 + l2 * p[2].2;
                let k = (y * w + x) as usize;
                if alpha >= 1.0 {
                    if z < self.depth[k] {
                        self.depth[k] = z;
                        self.rgb[k] = c;
                    }
                } else {
                    let old = self.rgb[k];
                    self.rgb[k] = [0, 1, 2].map(|i| alpha * c[i] + (1.0 - alpha) * old[i]);
                }
            }
        }
    }

    /// A line from `a` to `b`, `width` pixels wide, drawn over everything.
    pub fn line(&mut self, cam: &Camera, a: DVec3, b: DVec3, colour: [f64; 3], width: f64) {
        let (pa, pb) = (cam.project(a), cam.project(b));
        let len = ((pb.0 - pa.0).powi(2) + (pb.1 - pa.1).powi(2)).sqrt();
        let steps = (2.0 * len).ceil().max(1.0) as usize;
        let r = (0.5 * width).max(0.5);
        for s in 0..=steps {
            let f = s as f64 / steps as f64;
            let (x, y) = (pa.0 + f * (pb.0 - pa.0), pa.1 + f * (pb.1 - pa.1));
            let ri = r.ceil() as i64;
            for dy in -ri..=ri {
                for dx in -ri..=ri {
                    if ((dx * dx + dy * dy) as f64) <= r * r {
                        self.put(x as i64 + dx, y as i64 + dy, colour);
                    }
                }
            }
        }
    }

    fn put(&mut self, x: i64, y: i64, colour: [f64; 3]) {
        let (w, h) = (self.size.0 as i64, self.size.1 as i64);
        if (0..w).contains(&x) && (0..h).contains(&y) {
            self.rgb[(y * w + x) as usize] = colour;
        }
    }

    /// The colour at pixel (x, y).
    pub fn at(&self, x: u32, y: u32) -> [f64; 3] {
        self.rgb[(y * self.size.0 + x) as usize]
    }
}

/// The pixels from the least to the most of `c`, within 0..n.
fn pixel_span(c: [f64; 3], n: i64) -> (i64, i64) {
    let lo = c.iter().copied().fold(f64::INFINITY, f64::min).floor() as i64;
    let hi = c.iter().copied().fold(f64::NEG_INFINITY, f64::max).ceil() as i64;
    (lo.max(0), hi.min(n - 1))
}

/// A colour for `t` in [0, 1] on a perceptually ordered scale (viridis'
/// end points and three between).
pub fn scale(t: f64) -> [f64; 3] {
    const STOPS: [[f64; 3]; 5] = [
        [0.267, 0.005, 0.329],
        [0.231, 0.322, 0.545],
        [0.129, 0.569, 0.549],
        [0.369, 0.788, 0.384],
        [0.993, 0.906, 0.144],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f64;
    [0, 1, 2].map(|c| STOPS[i][c] + f * (STOPS[i + 1][c] - STOPS[i][c]))
}

/// A colour per category (body or material), repeating after twelve.
pub fn category(i: usize) -> [f64; 3] {
    const PALETTE: [[f64; 3]; 12] = [
        [0.122, 0.467, 0.706],
        [1.0, 0.498, 0.055],
        [0.173, 0.627, 0.173],
        [0.839, 0.153, 0.157],
        [0.580, 0.404, 0.741],
        [0.549, 0.337, 0.294],
        [0.890, 0.467, 0.761],
        [0.498, 0.498, 0.498],
        [0.737, 0.741, 0.133],
        [0.090, 0.745, 0.812],
        [0.682, 0.780, 0.910],
        [1.0, 0.733, 0.471],
    ];
    PALETTE[i % PALETTE.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square (two triangles) seen from above, filling the middle of
    /// the picture; a translucent one in front tints it; a line over both.
    #[test]
    fn a_square_fills_its_projection_and_nothing_else() {
        let s = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let size = (100, 100);
        let cam = Camera::fitting(-DVec3::Z, &s, size);
        let mut p = Picture::new(size, [1.0; 3]);
        let red = [1.0, 0.0, 0.0];
        p.triangle(&cam, [s[0], s[1], s[2]], red, 1.0);
        p.triangle(&cam, [s[0], s[2], s[3]], red, 1.0);
        // Seen squarely: full shade. The square spans 90% of the picture.
        assert_eq!(p.at(50, 50), red);
        assert_eq!(p.at(10, 10), red);
        assert_eq!(p.at(89, 89), red);
        assert_eq!(p.at(2, 2), [1.0; 3]);
        assert_eq!(p.at(97, 50), [1.0; 3]);
        // A nearer opaque triangle hides the square; a farther one does not.
        let far = s.map(|v| v - DVec3::Z);
        p.triangle(&cam, [far[0], far[1], far[2]], [0.0, 0.0, 1.0], 1.0);
        assert_eq!(p.at(80, 50), red);
        let near = s.map(|v| v + DVec3::Z);
        p.triangle(&cam, [near[0], near[1], near[2]], [0.0, 1.0, 0.0], 0.5);
        let tinted = p.at(80, 50);
        assert!(
            (tinted[0] - 0.5).abs() < 1e-12 && (tinted[1] - 0.5).abs() < 1e-12,
            "{tinted:?}"
        );
        p.line(&cam, s[0], s[2], [0.0; 3], 3.0);
        assert_eq!(p.at(50, 50), [0.0; 3]);
    }

    #[test]
    fn the_scale_runs_from_dark_to_light_and_clamps() {
        let lum = |c: [f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let l: Vec<f64> = (0..=10).map(|i| lum(scale(i as f64 / 10.0))).collect();
        assert!(l.windows(2).all(|w| w[1] > w[0]), "{l:?}");
        assert_eq!(scale(-1.0), scale(0.0));
        assert_eq!(scale(2.0), scale(1.0));
        assert_eq!(scale(f64::NAN), scale(0.0));
    }
}
