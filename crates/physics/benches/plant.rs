//! Plant step cost: one 1 ms controller period (10 internal sub-steps at the
//! default sub-step) and one single internal sub-step, on asphalt and snow.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use grip_physics::plant::DEFAULT_MAX_SUBSTEP;
use grip_physics::{FrictionModel, Plant, PlantState, Road, VehicleParams};

fn bench(c: &mut Criterion) {
    let p = VehicleParams::default();
    let roads = [
        Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap(),
        Road::burckhardt("snow", 0.1946, 94.129, 0.0646).unwrap(),
        Road::new(
            "pacejka",
            FrictionModel::Pacejka {
                b: 11.7,
                c: 1.69,
                d: 1.2,
                e: 0.377,
            },
        )
        .unwrap(),
        Road::new(
            "table",
            FrictionModel::Table {
                slip: vec![0.0, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0],
                mu: vec![0.0, 0.3, 0.52, 0.62, 0.64, 0.63, 0.6, 0.56, 0.53, 0.5],
            },
        )
        .unwrap(),
    ];
    for road in &roads {
        let start = PlantState::rolling(20.0 / 3.6, p.r);
        let mut plant = Plant::new(p, start).unwrap();
        let mut k = 0u32;
        c.bench_function(&format!("plant_step_1ms/{}", road.name()), |b| {
            b.iter(|| {
                // Keep the state in a realistic range: restart every 3 s of sim time.
                k += 1;
                if k == 3000 {
                    k = 0;
                    plant.set_state(start).unwrap();
                }
                plant.step(black_box(1e-3), black_box(300.0), road, black_box(0.0));
                black_box(plant.state().omega)
            })
        });
        let mut plant = Plant::new(p, start).unwrap();
        let mut k = 0u32;
        c.bench_function(&format!("plant_substep/{}", road.name()), |b| {
            b.iter(|| {
                k += 1;
                if k == 30_000 {
                    k = 0;
                    plant.set_state(start).unwrap();
                }
                plant.step(
                    black_box(DEFAULT_MAX_SUBSTEP),
                    black_box(300.0),
                    road,
                    black_box(0.0),
                );
                black_box(plant.state().omega)
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
