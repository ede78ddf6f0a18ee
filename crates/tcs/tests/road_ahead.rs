//! Road knowledge ahead of the wheel: the preview queue's invariants for
//! any decision sequence, the road under the wheel surviving a full queue
//! in `RoadAware`, and a road ahead that carries next to nothing.

use grip_physics::{Road, RoadCatalogue, VehicleParams};
use grip_tcs::{
    ControllerKind, ControllersConfig, KnowledgeConfig, Measurement, PREVIEW_CAPACITY,
    PreviewQueue, RoadAware, RoadTable,
};
use proptest::prelude::*;

/// μ_peak of the test roads: asphalt, gravel, snow, stone, ice; road 5 is
/// not in the catalogue (NaN: counts as carrying less than any).
const MU: [f64; 5] = [1.0, 0.5, 0.2, 1.1, 0.05];

fn mu(i: usize) -> f64 {
    MU.get(i).copied().unwrap_or(f64::NAN)
}

/// Does road `a` carry less than road `b` (the queue's cautious reading)?
fn carries_less(a: usize, b: usize) -> bool {
    let (m, o) = (mu(a), mu(b));
    m < o || m.is_nan() || o.is_nan()
}

/// One decision: the odometer advances by `step` m, then the microphone's
/// frame of `frame` m ending there names `road`; the queue gets it from
/// `change_at` of the frame on, `lead` m ahead.
#[derive(Debug, Clone)]
struct Decision {
    step: f64,
    frame: f64,
    change_at: f64,
    road: usize,
    confidence: f64,
}

fn decision(roads: usize) -> impl Strategy<Value = Decision> {
    (
        prop_oneof![Just(0.0), 0.0..0.02, 0.0..0.3],
        prop_oneof![Just(0.0), 0.0..0.2],
        prop_oneof![Just(0.0), Just(0.375), 0.0..1.0],
        prop_oneof![0..roads, 0..6usize],
        0.0..1.0,
    )
        .prop_map(|(step, frame, change_at, road, confidence)| Decision {
            step,
            frame,
            change_at,
            road,
            confidence,
        })
}

fn case() -> impl Strategy<Value = (f64, Vec<Decision>)> {
    (
        prop_oneof![Just(0.0), Just(0.5), Just(2.77), Just(20.0)],
        // Two roads flickering fill the queue; all six test the rest.
        prop_oneof![Just(2usize), Just(3usize), Just(6usize)],
    )
        .prop_flat_map(|(lead, roads)| (Just(lead), prop::collection::vec(decision(roads), 1..400)))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Entries stay ordered without overlap (each runs from its start to
    /// the next one's), begin no later than they are sure, and fit the
    /// capacity; a decision heard ahead of the wheel never loses the road
    /// under it: it stays, or a road that carries less replaces it; and a
    /// full queue changes nothing but its two farthest entries.
    #[test]
    fn queue_invariants_hold_for_any_decision_sequence((lead, ds) in case()) {
        let mut q = PreviewQueue::new();
        let mut x = 0.0_f64;
        for (k, d) in ds.iter().enumerate() {
            x += d.step;
            let here = q.view(x).here;
            let before: Vec<_> = q.entries().to_vec();
            let overflows = q.overflows();
            let x_from = x - d.frame + d.change_at * d.frame + lead;
            let x_to = x + lead;
            q.push(d.road, d.confidence, k as f64, x_from, x_to, mu);

            let e = q.entries();
            prop_assert!(e.len() <= PREVIEW_CAPACITY);
            prop_assert!(
                e.windows(2).all(|w| w[0].x_start < w[1].x_start),
                "not ordered after {}: {:?}", k, e
            );
            prop_assert!(e.iter().all(|r| r.x_sure >= r.x_start && r.hits >= 1));
            if q.overflows() > overflows {
                prop_assert_eq!(q.overflows(), overflows + 1);
                prop_assert_eq!(e.len(), PREVIEW_CAPACITY);
                prop_assert_eq!(&e[..PREVIEW_CAPACITY - 2], &before[..PREVIEW_CAPACITY - 2]);
                let (near, far) = (before[PREVIEW_CAPACITY - 2], before[PREVIEW_CAPACITY - 1]);
                let m = e[PREVIEW_CAPACITY - 2];
                prop_assert_eq!(m.x_start, near.x_start);
                prop_assert!(m.road == near.road || m.road == far.road);
                // The road kept carries no more than either (both known here).
                let known = !(mu(near.road).is_nan() || mu(far.road).is_nan());
                prop_assert!(
                    !known || !(carries_less(near.road, m.road) || carries_less(far.road, m.road)),
                    "merged {:?} and {:?} into {:?}", near, far, m
                );
                prop_assert_eq!(m.hits, near.hits.max(far.hits));
            }
            let after = q.view(x).here;
            if let Some(h0) = here
                && x_from > x
            {
                let h1 = after;
                prop_assert!(h1.is_some(), "the road under the wheel was lost after {}: {:?}", k, h0);
                let h1 = h1.unwrap();
                prop_assert!(
                    (h1.road, h1.x_start) == (h0.road, h0.x_start) || carries_less(h1.road, h0.road),
                    "a road that carries more replaced the one under the wheel after {}: {:?} -> {:?}",
                    k, h0, h1
                );
            }
        }
    }
}

#[test]
fn the_snow_under_the_wheel_keeps_its_cap_while_the_queue_overflows_ahead() {
    // The wheel is on snow; the microphone, 2.77 m ahead, hears asphalt and
    // stone alternate in confirmed pairs at a 25 ms hop and 1 m/s (under
    // the speed at which slip adds evidence: the acoustics decide alone):
    // an entry every 5 cm, 32 of them within 1.6 m, so the queue is full
    // long before the wheel reaches the first of them at about 2.74 m.
    let roads = RoadCatalogue::burckhardt(&["asphalt", "snow", "stone"]).unwrap();
    let (asphalt, snow, stone) = (0, 1, 2);
    let vehicle = VehicleParams {
        mic_lead_m: 2.77,
        ..Default::default()
    };
    let table = RoadTable::new(&roads, &KnowledgeConfig::default()).unwrap();
    let snow_cap = table.info(snow).mu_peak * vehicle.normal_force() * vehicle.r;
    let mut aware = RoadAware::new(
        ControllerKind::Mtte,
        &roads,
        table,
        &vehicle,
        &ControllersConfig::default(),
        1e-3,
    )
    .unwrap();
    let (speed, lambda, frame) = (1.0, 0.01, 0.1);
    // The same decisions into a queue of our own, to see it fill: as
    // `RoadAware::decision` queues them (from `change_at` of the frame on,
    // the lead ahead).
    let change_at = ControllersConfig::default().preview.change_at;
    let mut shadow = PreviewQueue::new();
    let mut decide = |aware: &mut RoadAware, road: usize, t: f64, x_from: f64, x_to: f64| {
        aware.decision(road, 0.9, t, x_from, x_to);
        let from = x_from + change_at * (x_to - x_from) + vehicle.mic_lead_m;
        shadow.push(road, 0.9, t, from, x_to + vehicle.mic_lead_m, |i| {
            roads.by_index(i).map_or(f64::NAN, |r| r.mu_peak())
        });
        shadow.overflows()
    };
    // Snow heard before the start, under the wheel from -0.19 m on.
    decide(&mut aware, snow, 0.0, -3.0, -2.9);
    decide(&mut aware, snow, 0.0, -2.9, -2.8);
    let mut overflows = 0;
    for k in 0..2700_u32 {
        let t = f64::from(k) * 1e-3;
        let x = speed * t;
        if k % 25 == 0 {
            let road = if (k / 50) % 2 == 0 { asphalt } else { stone };
            overflows = decide(&mut aware, road, t, x - speed * frame, x);
        }
        let m = Measurement {
            t,
            omega: speed / (1.0 - lambda) / vehicle.r,
            v: Some(speed),
            torque: roads[snow].mu(lambda) * vehicle.normal_force() * vehicle.r,
            demand: 300.0,
        };
        let g = aware.step(&m, x);
        let here = g
            .view
            .here
            .unwrap_or_else(|| panic!("at {x:.3} m the road under the wheel is lost"));
        assert_eq!(here.road, snow, "at {x:.3} m");
        assert!(
            g.torque_cap <= snow_cap * (1.0 + 1e-9),
            "at {x:.3} m the cap is {} N m, snow carries {snow_cap}",
            g.torque_cap
        );
    }
    assert!(overflows > 10, "the queue did not fill: {overflows} merges");
}

#[test]
fn a_road_ahead_that_carries_next_to_nothing_gives_its_cap_without_a_panic() {
    // μ_peak 1e-13 (`Road::new` takes any positive peak): its cap,
    // 1e-13 · N · r, lies under the floor the previewed drop is shaped with
    // (0.7 of at least 1e-9 N m), which once made `clamp` panic.
    let roads = RoadCatalogue::new(vec![
        Road::burckhardt("asphalt", 1.2801, 23.99, 0.52).unwrap(),
        Road::burckhardt("nothing", 1e-13, 20.0, 0.0).unwrap(),
    ])
    .unwrap();
    let vehicle = VehicleParams {
        mic_lead_m: 2.77,
        ..Default::default()
    };
    let table = RoadTable::new(&roads, &KnowledgeConfig::default()).unwrap();
    let target = table.info(1).mu_peak * vehicle.normal_force() * vehicle.r;
    assert!(target > 0.0 && target < 1e-9, "{target}");
    let mut aware = RoadAware::new(
        ControllerKind::Mtte,
        &roads,
        table,
        &vehicle,
        &ControllersConfig::default(),
        1e-3,
    )
    .unwrap();
    let speed = 5.0;
    // Asphalt under the wheel, the other road from 2.5 m on (0.5 s ahead).
    aware.decision(0, 0.9, 0.0, -3.0, -2.9);
    aware.decision(0, 0.9, 0.0, -2.9, -2.8);
    aware.decision(1, 0.9, 0.0, -0.27, -0.17);
    aware.decision(1, 0.9, 0.0, -0.17, -0.07);
    let mut capped = false;
    for k in 0..400_u32 {
        let t = f64::from(k) * 1e-3;
        let g = aware.step(
            &Measurement {
                t,
                omega: speed / 0.99 / vehicle.r,
                v: Some(speed),
                torque: 300.0,
                demand: 300.0,
            },
            speed * t,
        );
        assert!(g.torque_cap >= 0.0, "{}", g.torque_cap);
        capped |= g.torque_cap <= target;
    }
    assert!(capped, "the drop towards the road was never shaped");
}
