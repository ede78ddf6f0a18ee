//! Pieces of constructed drive logs shared by the tests of grip-drive and
//! grip (the summary's and `grip inspect`'s control-health tests).

use grip_msgs::{GroundTruth, name_to_bytes};

/// The plant's ground truth at its cycle `k` of a 1 ms period on asphalt:
/// standing for the first 10 cycles (the scenario starts at cycle 9, the
/// last sample before x first changes), then rolling at 3 m/s, 3 mm a cycle,
/// the wheel at 10 rad/s.
pub fn asphalt_truth(k: u64) -> GroundTruth {
    let mut g = GroundTruth::zeroed();
    g.seq = k;
    g.stamp_ns = k * 1_000_000;
    g.x = if k < 10 { 0.0 } else { (k - 9) as f64 * 0.003 };
    g.v = 3.0;
    g.omega = 10.0;
    g.road_index = 0;
    g.road_name = name_to_bytes("asphalt");
    g.mic_road_index = 0;
    g.mic_road_name = g.road_name;
    g
}
