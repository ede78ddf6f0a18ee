use super::*;
use iceoryx2::prelude::ZeroCopySend;

/// Compile-time proof that a type is a plain, copyable, shared-memory-safe
/// value: `Copy` rules out `Drop` and owned heap data (Box, Vec, String),
/// `ZeroCopySend` (derived field by field) rules out references and raw
/// pointers, `'static` rules out borrowed data.
fn assert_plain<T: ZeroCopySend + Copy + Send + Sync + 'static>() -> &'static str {
    // SAFETY: type_name is unsafe only because implementors must keep layouts
    // in sync across languages; reading it is harmless.
    unsafe { <T as ZeroCopySend>::type_name() }
}

#[test]
fn every_payload_is_plain_and_has_its_versioned_name() {
    assert_eq!(assert_plain::<AudioBlock>(), AudioBlock::TYPE_NAME);
    assert_eq!(assert_plain::<RoadEstimate>(), RoadEstimate::TYPE_NAME);
    assert_eq!(assert_plain::<CycleRecord>(), CycleRecord::TYPE_NAME);
    assert_eq!(assert_plain::<CanFrame>(), CanFrame::TYPE_NAME);
    assert_eq!(assert_plain::<GroundTruth>(), GroundTruth::TYPE_NAME);
    assert_eq!(assert_plain::<E2eFaults>(), E2eFaults::TYPE_NAME);
    for name in [
        AudioBlock::TYPE_NAME,
        RoadEstimate::TYPE_NAME,
        CycleRecord::TYPE_NAME,
        CanFrame::TYPE_NAME,
        GroundTruth::TYPE_NAME,
    ] {
        assert!(
            name.starts_with("grip::") && (name.ends_with("::v1") || name.ends_with("::v2")),
            "{name}"
        );
    }
}

#[test]
fn sizes_and_alignment() {
    use core::mem::{align_of, size_of};
    assert_eq!(size_of::<AudioBlock>(), 32 + 2 * AUDIO_MAX_SAMPLES);
    assert_eq!(size_of::<CanFrame>(), 24);
    assert_eq!(size_of::<RoadEstimate>(), 136);
    assert_eq!(size_of::<CycleRecord>(), 160);
    assert_eq!(size_of::<GroundTruth>(), 96);
    assert_eq!(align_of::<CycleRecord>(), 8);
    // field offsets a C reader would rely on
    assert_eq!(core::mem::offset_of!(CanFrame, data), 16);
    assert_eq!(core::mem::offset_of!(AudioBlock, samples), 32);
    assert_eq!(core::mem::offset_of!(CycleRecord, faults), 132);
}

#[test]
fn names_round_trip_and_truncate_on_char_boundary() {
    let b = name_to_bytes("asphalt");
    assert_eq!(name_from_bytes(&b), Some("asphalt"));
    let b = name_to_bytes("wet_cobblestone_long_name");
    assert_eq!(name_from_bytes(&b), Some("wet_cobblestone_"));
    // "ü" is two bytes; 15 ASCII + "ü" must not split the character
    let b = name_to_bytes("aaaaaaaaaaaaaaaü");
    assert_eq!(name_from_bytes(&b), Some("aaaaaaaaaaaaaaa"));
    let mut bad = [0u8; NAME_LEN];
    bad[0] = 0xff;
    assert_eq!(name_from_bytes(&bad), None);
}

#[test]
fn accessors_clamp_corrupt_lengths() {
    let mut a = AudioBlock::zeroed();
    a.n_samples = u32::MAX;
    assert_eq!(a.samples().len(), AUDIO_MAX_SAMPLES);
    a.n_samples = 3;
    assert_eq!(a.samples().len(), 3);
    let mut f = CanFrame::new(0x100, &[1, 2, 3]);
    assert_eq!(f.payload(), &[1, 2, 3]);
    f.dlc = 200;
    assert_eq!(f.payload().len(), 8);
    assert_eq!(CanFrame::new(1, &[9; 12]).dlc, 8);
}

#[test]
fn topics_are_unique_valid_service_names() {
    let mut seen = std::collections::HashSet::new();
    for (t, _) in topics::ALL {
        assert!(seen.insert(t), "duplicate topic {t}");
        let n: Result<iceoryx2::prelude::ServiceName, _> = t.try_into();
        assert!(n.is_ok(), "{t} is not a valid iceoryx2 service name");
    }
}

proptest::proptest! {
    #[test]
    fn e2e_fault_total_is_sum(a in proptest::array::uniform6(0u32..1_000_000)) {
        let f = E2eFaults { crc: a[0], counter_repeated: a[1], counter_skipped: a[2],
            length: a[3], unknown_id: a[4], timeout: a[5] };
        let mut g = E2eFaults::default();
        g.add(&f);
        g.add(&f);
        proptest::prop_assert_eq!(g.total(), 2 * a.iter().map(|&x| u64::from(x)).sum::<u64>());
    }
}
