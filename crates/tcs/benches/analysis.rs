//! ν-gap cost (not a hot path: run by `grip analyze`; measured for the README).

use criterion::{Criterion, criterion_group, criterion_main};
use grip_tcs::analysis::{Poly, Tf, nu_gap};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let p1 = Tf::from_coeffs(&[100.0], &[2.0, 1.0]).unwrap();
    let p2 = Tf::from_coeffs(&[100.0], &[2.0, -1.0]).unwrap();
    c.bench_function("nu_gap first order (Vinnicombe example)", |b| {
        b.iter(|| nu_gap(black_box(&p1), black_box(&p2)).unwrap())
    });
    let q1 = Tf::from_coeffs(&[1.0, 2.0, 1.0], &[1.0, 3.0, 5.0, 4.0, 1.0]).unwrap();
    let q2 = Tf::from_coeffs(&[1.2, 1.0, -1.0], &[1.0, 2.0, 6.0, 3.0, -0.5]).unwrap();
    c.bench_function("nu_gap fourth order", |b| {
        b.iter(|| nu_gap(black_box(&q1), black_box(&q2)).unwrap())
    });
    let p8 = Poly::new(&[1.0, -2.0, 3.0, 0.5, -1.0, 2.0, 0.25, 1.0, -3.0]).unwrap();
    c.bench_function("roots degree 8", |b| {
        b.iter(|| black_box(&p8).roots().unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
