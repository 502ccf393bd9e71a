//! Criterion benchmarks of the triangle-distance kernels against parry3d-f64,
//! on the same random pairs, one thread, in one run: compare the rows.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use dem::distance::{
    distance_many, distance_triangle_triangle, penalty_scalar, random_unit_pairs, Closest, Method,
    Options, PenaltyParams, PenaltyStats,
};
use parry3d_f64::math::{Pose, Vector};
use parry3d_f64::shape::Triangle as ParryTriangle;
use std::hint::black_box;

const PAIRS: usize = 10_000;

fn kernels(c: &mut Criterion) {
    let pairs = random_unit_pairs(PAIRS, 1);
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut g = c.benchmark_group("triangle_distance");
    g.throughput(Throughput::Elements(PAIRS as u64));
    for method in [Method::Brute, Method::Penalty, Method::Hybrid] {
        let opts = Options {
            method,
            ..Options::default()
        };
        // Answers go to buffers allocated once, as `tridem kernels` does: a
        // fresh 640 kB answer vector per iteration is a fresh mapping, and
        // its page faults cost about a tenth of the kernel's time.
        let mut out = vec![Closest::UNSET; PAIRS];
        let mut stats = vec![PenaltyStats::default(); PAIRS];
        g.bench_function(BenchmarkId::new(method.name(), "batch8"), |b| {
            b.iter(|| {
                one_thread.install(|| {
                    black_box(distance_many(&pairs, &opts, &mut out, &mut stats).unwrap())
                })
            })
        });
    }
    let prm = PenaltyParams::default();
    g.bench_function(BenchmarkId::new("penalty", "scalar"), |b| {
        b.iter(|| {
            for (a, t) in &pairs {
                black_box(penalty_scalar(a, t, &prm));
            }
        })
    });
    g.bench_function(BenchmarkId::new("brute", "direct"), |b| {
        b.iter(|| {
            for (a, t) in &pairs {
                black_box(distance_triangle_triangle(a, t));
            }
        })
    });
    let v = |p: glam::DVec3| Vector::new(p.x, p.y, p.z);
    let parry: Vec<_> = pairs
        .iter()
        .map(|(a, t)| {
            (
                ParryTriangle::new(v(a[0]), v(a[1]), v(a[2])),
                ParryTriangle::new(v(t[0]), v(t[1]), v(t[2])),
            )
        })
        .collect();
    let id = Pose::IDENTITY;
    g.bench_function(BenchmarkId::new("parry3d-f64", "gjk"), |b| {
        b.iter(|| {
            for (a, t) in &parry {
                black_box(parry3d_f64::query::distance(&id, a, &id, t).unwrap());
            }
        })
    });
    g.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
