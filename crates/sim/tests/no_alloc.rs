//! `Sim::step` allocates nothing: a counting global allocator around the
//! per-cycle loop of every variant, with the trace recorded (it is
//! preallocated to the run length) and the confusion-matrix ARTE in the loop;
//! with the paper's placement (fusion only) and with the front-arch
//! microphone (the preview queue, the road belief and the torque cap); the
//! MFC with its noise low-pass and the metrics with the command's figures;
//! and the front-arch ARTE variants on a hill start that rolls back (the
//! reverse detection clearing the preview queue). Also `grip_sim::ideal::ideal_run`.

mod common;

use grip_sim::{Sim, Variant};

#[global_allocator]
static A: grip_testkit::CountingAlloc = grip_testkit::CountingAlloc;

fn allocs() -> u64 {
    grip_testkit::thread_allocations()
}

#[test]
fn the_cycle_allocates_nothing() {
    let (setup, est) = common::reference();
    // The shipped MFC runs with its noise low-pass: its state is in the proof.
    assert!(setup.controllers().mfc.tau_noise > 0.0);
    let dir = grip_config::ConfigDir::new(common::config_dir());
    let (vehicle, sensors) =
        grip_config::load_vehicle(common::config_dir().join("vehicles/front-mic.toml")).unwrap();
    let front = grip_sim::SimSetup::new(
        vehicle,
        sensors,
        setup.roads().clone(),
        setup.scenario().clone(),
        *setup.controllers(),
        &dir.knowledge(setup.roads()).unwrap(),
    )
    .unwrap();
    for (setup, v) in Variant::ALL
        .iter()
        .map(|&v| (&setup, v))
        .chain(Variant::ALL.iter().filter(|v| v.arte).map(|&v| (&front, v)))
    {
        let mut e = est.clone();
        let mut sim = Sim::new(setup, v, 11, &mut e, true).unwrap();
        let before = allocs();
        let mut cycles = 0;
        while sim.step() {
            cycles += 1;
        }
        let during = allocs() - before;
        assert_eq!(cycles, setup.cycles());
        assert_eq!(during, 0, "{v}: {during} allocations in {cycles} cycles");
        let r = sim.finish();
        assert_eq!(r.trace.as_ref().map(|t| t.len()), Some(setup.cycles()));
    }
    // A hill start that rolls back (tests/data/rollback.toml): the road
    // knowledge detects the reverse, clears its queue and drops decisions.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/rollback.toml");
    let rollback = grip_sim::SimSetup::new(
        vehicle,
        sensors,
        setup.roads().clone(),
        dir.scenario_with(path.to_str().unwrap(), setup.roads())
            .unwrap(),
        *setup.controllers(),
        &dir.knowledge(setup.roads()).unwrap(),
    )
    .unwrap();
    for v in Variant::ALL.iter().filter(|v| v.arte) {
        let mut e = est.clone();
        let mut sim = Sim::new(&rollback, *v, 11, &mut e, true).unwrap();
        let before = allocs();
        while sim.step() {}
        let during = allocs() - before;
        assert_eq!(during, 0, "{v} rolling back: {during} allocations");
        assert!(
            sim.finish().final_state.v > 0.0,
            "{v}: the roll-back stopped"
        );
    }
    // The counter works: a Vec allocates.
    let before = allocs();
    let v: Vec<u8> = Vec::with_capacity(10);
    assert!(allocs() > before);
    drop(v);
}

#[test]
fn the_ideal_controller_allocates_nothing() {
    // grip_sim::ideal::ideal_run on the reference scenario, both holds:
    // its loop over the cycles has no buffer to grow.
    let (setup, _) = common::reference();
    for hold in [
        grip_sim::ideal::Hold::Share(0.8),
        grip_sim::ideal::Hold::Slope(5.0),
    ] {
        let before = allocs();
        let r = grip_sim::ideal::ideal_run(
            setup.vehicle(),
            setup.roads().roads(),
            setup.scenario(),
            setup.dt(),
            setup.cycles(),
            hold,
        );
        let during = allocs() - before;
        assert!(r.mean_accel > 0.0, "{hold}: {r:?}");
        assert_eq!(during, 0, "{hold}: {during} allocations");
    }
}
