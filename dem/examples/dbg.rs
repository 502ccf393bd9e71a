use dem::distance::*;
use glam::DVec3;
fn main() {
    let line = std::env::args().nth(1).unwrap();
    let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
    let p = |k: usize| DVec3::new(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
    let a = [p(0), p(1), p(2)];
    let b = [p(3), p(4), p(5)];
    let r = distance_triangle_triangle(&a, &b);
    println!("{r:?}");
    for rot in 0..3 {
        let t = [b[rot], b[(rot+1)%3], b[(rot+2)%3]];
        let o = t[0];
        let local = [DVec3::ZERO, t[1]-o, t[2]-o];
        let x = r.q - o;
        let c = closest_point_triangle(x, &local);
        println!("rot {rot}: off {:e}", (c-x).length());
    }
    let n = (b[1]-b[0]).cross(b[2]-b[0]);
    println!("edges {:e} {:e} {:e} |n| {:e}", (b[1]-b[0]).length(), (b[2]-b[1]).length(), (b[0]-b[2]).length(), n.length());
}
