//! The whole six-variant reference run (`config/scenarios/paper.toml`, one
//! seed, confusion-matrix ARTE, traces off), single-threaded. Real-time
//! factor = 6 × simulated seconds / wall seconds per iteration.

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::Path;

use grip_config::{ConfigDir, parse_toml, read_file};
use grip_sim::{ArteConfig, ConfusionArte, Sim, SimSetup, Variant};
use grip_tcs::ControllersConfig;

fn setup() -> (SimSetup, ConfusionArte) {
    let dir = ConfigDir::new(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config"));
    let (vehicle, sensors) = dir.vehicle().expect("vehicle.toml");
    let roads = dir.roads().expect("roads.toml");
    let scenario = dir.scenario_with("paper", &roads).expect("paper.toml");
    let cpath = dir.file("controllers.toml");
    let controllers: ControllersConfig =
        parse_toml(&cpath, &read_file(&cpath).expect("read")).expect("controllers.toml");
    let apath = dir.file("sim-confusion.toml");
    let arte: ArteConfig =
        parse_toml(&apath, &read_file(&apath).expect("read")).expect("sim-confusion.toml");
    let est = ConfusionArte::new(&arte.confusion, &roads).expect("confusion");
    let setup = SimSetup::new(
        vehicle,
        sensors,
        roads,
        scenario,
        controllers,
        &grip_tcs::KnowledgeConfig::default(),
    )
    .expect("setup");
    (setup, est)
}

fn bench(c: &mut Criterion) {
    let (setup, est) = setup();
    let mut e = est.clone();
    let mut g = c.benchmark_group("reference");
    g.sample_size(30);
    g.bench_function("six_variants_one_seed", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for v in Variant::ALL {
                let r = Sim::new(&setup, v, 1, &mut e, false).expect("sim").finish();
                acc += r.metrics.slip_deviation;
            }
            black_box(acc)
        })
    });
    g.finish();
    eprintln!(
        "simulated per iteration of six_variants_one_seed: 6 x {:.3} s = {:.3} s",
        setup.sim_time(),
        6.0 * setup.sim_time()
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
