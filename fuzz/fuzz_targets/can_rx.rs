//! The CAN receive path: arbitrary frames at arbitrary times into
//! `ProtocolRx` (both nodes: tcs-loop's four sensor messages and the
//! inverter's torque command) and into a whole `TcsLoop` (the shipped
//! configuration; controller and ARTE chosen by the input) whose cycles then
//! run on the decoded values.
//!
//! Input: one set-up byte (controller kind, ARTE on/off), then 12-byte
//! records `[flags, id, dlc, dt, data0..data7]`:
//! - `flags` bit 0: write the correct E2E CRC into `data[0]` (so that the
//!   payload reaches the decoders and the controller, not only the CRC
//!   check); bit 1: write the next alive counter of that id; bit 2: run one
//!   loop cycle after this frame; bit 3: the frame is not sent at all (only
//!   time passes);
//! - `id`: 0..=4 the protocol's messages (`config/inverter.dbc`), otherwise
//!   a raw identifier built from the byte (unknown ids, extended flag);
//! - `dlc`: as received (not clamped: a driver could hand anything);
//! - `dt`: time advance before the frame, in units of 0.1 ms.
//!
//! Checked besides "no panic": every frame is accounted for exactly once by
//! `ProtocolRx` (accepted, ignored, or one fault counter); an accepted frame
//! has the message's DLC and a correct CRC; every command the loop sends is
//! a valid E2E frame whose torque is finite, and zero with `Enable` cleared
//! in the safe state.
#![no_main]

use grip_io::can::protocol::{
    E2eError, InverterMsg, MESSAGES, ProtocolRx, TORQUE_COMMAND, counter_of, e2e_crc, spec_for_id,
};
use grip_io::can::{CanBus, CanFrame, MemBus};
use grip_io::clock::ManualClock;
use grip_msgs::{CycleRecord, can_flags};
use grip_tcs::ControllerKind;
use grip_tcs_loop::{CycleTick, NoRoad, RecordSink, TcsLoop};
use libfuzzer_sys::fuzz_target;

/// Counts what `ProtocolRx::receive` answered.
#[derive(Default)]
struct Tally {
    accepted: u64,
    ignored: u64,
    rejected: u64,
}

fn feed(rx: &mut ProtocolRx, t: &mut Tally, f: &CanFrame, now: u64) {
    match rx.receive(f, now) {
        Ok(Some(msg)) => {
            let spec = spec_for_id(f.id).expect("accepted frame of a protocol id");
            assert_eq!(f.dlc, spec.dlc, "accepted frame with a wrong DLC");
            assert_eq!(
                f.data[0],
                e2e_crc(spec.data_id, &f.data),
                "accepted with a bad CRC"
            );
            assert_eq!(InverterMsg::decode_unchecked(f), Some(msg));
            t.accepted += 1;
        }
        Ok(None) => t.ignored += 1,
        Err(E2eError::WrongReceiver { .. }) => {
            panic!("ProtocolRx dispatched to the wrong receiver")
        }
        Err(_) => t.rejected += 1,
    }
}

fn check_tally(rx: &ProtocolRx, t: &Tally, frames: u64) {
    let f = rx.faults();
    let counted = u64::from(f.crc)
        + u64::from(f.counter_repeated)
        + u64::from(f.counter_skipped)
        + u64::from(f.length)
        + u64::from(f.unknown_id);
    assert_eq!(counted, t.rejected, "faults counted != frames rejected");
    assert_eq!(t.accepted + t.ignored + t.rejected, frames);
    let accepted: u64 = MESSAGES
        .iter()
        .filter_map(|m| rx.receiver(m.id))
        .map(|r| r.accepted())
        .sum();
    assert_eq!(accepted, t.accepted);
}

/// Keeps what the loop publishes, to check it.
struct Sink {
    last: Option<CycleRecord>,
}

impl RecordSink for Sink {
    fn cycle(&mut self, rec: &CycleRecord) {
        self.last = Some(*rec);
    }
    fn can(&mut self, _frame: &CanFrame) {}
}

fn raw_id(b: u8) -> (u32, u8) {
    match b % 4 {
        // an 11-bit id near the protocol's
        0 => (0x100 + u32::from(b), 0),
        // the largest standard id
        1 => (0x7FF, 0),
        // an extended id that aliases a protocol id in its low bits
        2 => (0x1000_0110 | u32::from(b) << 12, can_flags::EXTENDED),
        _ => (u32::from(b) << 3, 0),
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&setup, records)) = data.split_first() else {
        return;
    };
    let repo = grip_fuzz::repo();
    let kind = [
        ControllerKind::Mfc,
        ControllerKind::Src,
        ControllerKind::Mtte,
    ][usize::from(setup % 3)];
    let arte = setup & 0x80 != 0;
    let lp = TcsLoop::new(
        kind,
        arte,
        &repo.controllers,
        &repo.vehicle,
        &repo.tcs_loop.safety,
    )
    .expect("TcsLoop from the shipped configuration");
    let mut lp = lp
        .with_road_aware(
            &repo.roads,
            repo.table.clone(),
            &repo.controllers,
            &repo.vehicle,
        )
        .expect("road knowledge from the shipped configuration");

    let (mut ecu, mut wire) = MemBus::pair();
    let clock = ManualClock::new(1_000_000_000);
    let mut now = 1_000_000_000u64;
    let mut tcs_rx = ProtocolRx::for_tcs();
    let mut inv_rx = ProtocolRx::for_inverter();
    let (mut tcs_t, mut inv_t) = (Tally::default(), Tally::default());
    let mut counters = [0u8; 5];
    let mut sent = 0u64;
    let mut sink = Sink { last: None };
    let mut deadline = now;
    let mut inverter = ProtocolRx::for_inverter();

    for r in records.chunks_exact(12) {
        let (flags, idb, dlc, dt) = (r[0], r[1], r[2], r[3]);
        now += u64::from(dt) * 100_000;
        clock.set_ns(now);
        if flags & 8 == 0 {
            let (id, fl) = match MESSAGES.get(usize::from(idb)) {
                Some(m) => (m.id, 0),
                None => raw_id(idb),
            };
            let mut f = CanFrame {
                stamp_ns: now,
                id,
                dlc,
                direction: 0,
                bus: 0,
                flags: fl,
                data: r[4..12].try_into().expect("8 bytes"),
            };
            if let Some(i) = MESSAGES.iter().position(|m| m.id == id) {
                if flags & 2 != 0 {
                    counters[i] = (counters[i] + 1) & 0x0F;
                    f.data[1] = (f.data[1] & 0xF0) | counters[i];
                }
                if flags & 1 != 0 {
                    f.data[0] = e2e_crc(MESSAGES[i].data_id, &f.data);
                }
            }
            feed(&mut tcs_rx, &mut tcs_t, &f, now);
            feed(&mut inv_rx, &mut inv_t, &f, now);
            sent += 1;
            wire.send(&f).expect("the memory bus takes a frame");
        }
        if flags & 4 != 0 {
            deadline = deadline.max(now);
            let tick = CycleTick::at(deadline);
            let rec = *lp.cycle(&tick, &clock, &mut ecu, &mut NoRoad, &mut sink);
            deadline += 1_000_000;
            assert!(rec.torque_cmd.is_finite(), "non-finite torque command");
            if rec.safe_state != 0 {
                assert_eq!(rec.torque_cmd, 0.0, "torque commanded in the safe state");
            }
            // the command on the wire is a valid frame the inverter accepts
            // (its counter follows the previous command)
            while let Ok(Some(cmd)) = wire.try_recv() {
                assert_eq!(cmd.id, TORQUE_COMMAND.id);
                assert_eq!(cmd.data[0], e2e_crc(TORQUE_COMMAND.data_id, &cmd.data));
                match inverter.receive(&cmd, now) {
                    Ok(Some(InverterMsg::TorqueCommand(c))) => {
                        assert!(c.torque_request.is_finite());
                        if rec.safe_state != 0 {
                            assert!(!c.enable, "Enable set in the safe state");
                        }
                    }
                    other => panic!("inverter refused command {}: {other:?}", counter_of(&cmd)),
                }
            }
        }
        tcs_rx.poll_timeouts(now);
        inv_rx.poll_timeouts(now);
    }
    check_tally(&tcs_rx, &tcs_t, sent);
    check_tally(&inv_rx, &inv_t, sent);
    if let Some(rec) = sink.last {
        assert!(rec.torque_cmd.is_finite());
    }
});
