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
    assert_eq!(p.road.poll_latest(), None);
    assert_eq!(p.road.errors, 0);
    // the recorder's topics still work
    p.sink.cycle(&CycleRecord::zeroed());
    assert_eq!((p.sink.cycle_published, p.sink.errors), (1, 0));
}
