//! The loop's iceoryx2 ports besides CAN: a topic that cannot be opened
//! (here: another payload type on it, as after a partial upgrade) is left
//! out and named, and the loop still gets the others; nothing is fatal.

use grip_io::ipc::IpcNode;
use grip_msgs::{CycleRecord, GroundTruth};
use grip_tcs_loop::ports::{RecordSink, RoadSource, open_ports};

#[test]
fn a_topic_that_cannot_be_opened_is_left_out_not_fatal() {
    let id = std::process::id();
    let (cycle, can, road) = (
        format!("test/tcs-ports/{id}/cycle"),
        format!("test/tcs-ports/{id}/can"),
        format!("test/tcs-ports/{id}/road"),
    );
    let node = IpcNode::create("tcs-ports-test").unwrap();
    // all three fresh: all open
    let ok = open_ports(&node, &cycle, &can, &road);
    assert!(ok.missing.is_empty(), "{:?}", ok.missing);
    assert!(ok.sink.cycle.is_some() && ok.sink.can.is_some() && ok.road.sub.is_some());
    drop(ok);

    // ROAD carries another payload type (another grip version's estimate)
    let road2 = format!("{road}-other");
    let _other = node.publisher::<GroundTruth>(&road2).unwrap();
    let mut p = open_ports(&node, &cycle, &can, &road2);
    assert_eq!(p.missing.len(), 1, "{:?}", p.missing);
    assert_eq!(p.missing[0].0, road2);
    assert!(!p.missing[0].1.is_empty());
    assert!(p.road.sub.is_none());
    assert_eq!(p.road.poll_next(), None);
    assert_eq!(p.road.errors, 0);
    // the recorder's topics still work
    p.sink.cycle(&CycleRecord::zeroed());
    assert_eq!((p.sink.cycle_published, p.sink.errors), (1, 0));
}

/// Every road estimate counts (each says what lies on its own stretch of
/// the path): a burst that arte publishes at once, after catching up on
/// its audio, reaches the loop whole and in order, not only its newest
/// (the subscriber's buffer of one before 2026-12-05 kept the last alone).
/// More than the buffer holds: the oldest are overwritten.
#[test]
fn a_burst_of_estimates_reaches_the_loop_whole_and_in_order() {
    use grip_msgs::RoadEstimate;
    use grip_tcs_loop::ROAD_BUFFER;
    let id = std::process::id();
    let (cycle, can, road) = (
        format!("test/tcs-burst/{id}/cycle"),
        format!("test/tcs-burst/{id}/can"),
        format!("test/tcs-burst/{id}/road"),
    );
    let node = IpcNode::create("tcs-burst-test").unwrap();
    let mut p = open_ports(&node, &cycle, &can, &road);
    assert!(p.missing.is_empty(), "{:?}", p.missing);
    let publisher = node.publisher::<RoadEstimate>(&road).unwrap();
    let est = |seq: u64| RoadEstimate {
        seq,
        ..RoadEstimate::zeroed()
    };
    // 20 at once: arte's default max_lag_s of 0.5 s at 40 estimates a second
    for seq in 1..=20 {
        publisher.publish(&est(seq)).unwrap();
    }
    let mut got = Vec::new();
    while let Some(e) = p.road.poll_next() {
        got.push(e.seq);
    }
    assert_eq!(got, (1..=20).collect::<Vec<u64>>());
    assert_eq!(p.road.errors, 0);
    // more than the buffer: the newest ROAD_BUFFER are kept, in order
    let n = ROAD_BUFFER as u64 + 10;
    for seq in 100..100 + n {
        publisher.publish(&est(seq)).unwrap();
    }
    let mut got = Vec::new();
    while let Some(e) = p.road.poll_next() {
        got.push(e.seq);
    }
    assert_eq!(got, (110..100 + n).collect::<Vec<u64>>());
}
