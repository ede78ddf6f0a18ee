//! [`MemBus`]: an in-process CAN bus for single-threaded tests and offline
//! replay of a service's cycle function, with no kernel, no iceoryx2 and no
//! other process. A participant reads its `rx` queue and writes its `tx`
//! queue; the test (or [`MemBus::pair`]'s other end) feeds and drains them.
//! Queues are preallocated (65 536 frames), so `send` and `try_recv`
//! allocate nothing while under that capacity (the services' no-allocation
//! tests rely on it). It receives every queued frame unless given a
//! [`RxFilter`] ([`MemBus::with_rx_filter`]), which it applies as SocketCAN's
//! kernel and the simulated bus do. Not `Send`: one thread only.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use core::time::Duration;

use super::{BusKind, CanBus, CanError, RxFilter};
use crate::clock::ManualClock;
use grip_msgs::{CanFrame, can_dir};

/// A frame queue shared between a [`MemBus`] and its feeder.
pub type FrameQueue = Rc<RefCell<VecDeque<CanFrame>>>;

/// Frames a queue holds before it would have to grow.
pub const MEM_BUS_CAPACITY: usize = 1 << 16;

/// A new preallocated queue.
pub fn frame_queue() -> FrameQueue {
    Rc::new(RefCell::new(VecDeque::with_capacity(MEM_BUS_CAPACITY)))
}

/// One participant of an in-process bus: reads `rx`, writes `tx`.
#[derive(Clone)]
pub struct MemBus {
    /// What this participant receives (fed by the test or the other end).
    pub rx: FrameQueue,
    /// What this participant sent.
    pub tx: FrameQueue,
    /// [`MemBus::deliver_late`]: the clock advanced before the next frame.
    late: Option<(ManualClock, u64)>,
    /// What `try_recv` hands over; the rest of `rx` is dropped unseen.
    filter: RxFilter,
    /// The bus number received frames are stamped with
    /// ([`MemBus::with_bus_id`]); `None`: left as fed.
    bus_id: Option<u8>,
}

impl Default for MemBus {
    fn default() -> Self {
        Self::new()
    }
}

impl MemBus {
    /// A participant whose queues the caller feeds and reads directly.
    pub fn new() -> Self {
        Self {
            rx: frame_queue(),
            tx: frame_queue(),
            late: None,
            filter: RxFilter::All,
            bus_id: None,
        }
    }

    /// Receives only what `rx` lets through, as a bus opened with it by
    /// [`super::open_bus`] would (the queue keeps everything fed to it;
    /// `try_recv` drops what does not pass).
    pub fn with_rx_filter(mut self, rx: RxFilter) -> Self {
        self.filter = rx;
        self
    }

    /// Stamps the frames it receives with bus number `bus_id`, as a
    /// SocketCAN or simulated bus opened with `can.toml`'s `bus_id` does
    /// (`grip generate` and the closed-loop replay give it the loop's, so
    /// their CAN log numbers received and sent frames alike).
    pub fn with_bus_id(mut self, bus_id: u8) -> Self {
        self.bus_id = Some(bus_id);
        self
    }

    /// Two participants wired to each other (one's `tx` is the other's `rx`).
    pub fn pair() -> (Self, Self) {
        let (a, b) = (frame_queue(), frame_queue());
        (
            Self {
                rx: a.clone(),
                tx: b.clone(),
                late: None,
                filter: RxFilter::All,
                bus_id: None,
            },
            Self {
                rx: b,
                tx: a,
                late: None,
                filter: RxFilter::All,
                bus_id: None,
            },
        )
    }

    /// Queues `f` for this participant to receive.
    pub fn inject(&self, f: CanFrame) {
        self.rx.borrow_mut().push_back(f);
    }

    /// Everything this participant sent since the last call, in order.
    pub fn take_sent(&self) -> Vec<CanFrame> {
        self.tx.borrow_mut().drain(..).collect()
    }

    /// The next frame received arrives `delay_ns` late: `clock` advances
    /// by that much just before `try_recv` hands it over, as when the
    /// receiving thread was preempted between its clock read and its drain
    /// and the frame reached the socket meanwhile.
    pub fn deliver_late(&mut self, clock: &ManualClock, delay_ns: u64) {
        self.late = Some((clock.clone(), delay_ns));
    }

    /// Forgets what this participant sent.
    pub fn clear_sent(&self) {
        self.tx.borrow_mut().clear();
    }
}

impl CanBus for MemBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), CanError> {
        self.tx.borrow_mut().push_back(*frame);
        Ok(())
    }
    /// The next queued frame the filter passes, marked as received.
    fn try_recv(&mut self) -> Result<Option<CanFrame>, CanError> {
        let f = {
            let mut q = self.rx.borrow_mut();
            loop {
                match q.pop_front() {
                    Some(f) if !self.filter.accepts(&f) => {}
                    other => break other,
                }
            }
        };
        if f.is_some()
            && let Some((clock, delay_ns)) = self.late.take()
        {
            clock.advance_ns(delay_ns);
        }
        Ok(f.map(|mut f| {
            f.direction = can_dir::RX;
            if let Some(b) = self.bus_id {
                f.bus = b;
            }
            f
        }))
    }
    /// As [`MemBus::try_recv`]: nobody else can fill the queue meanwhile.
    fn recv_timeout(&mut self, _: Duration) -> Result<Option<CanFrame>, CanError> {
        self.try_recv()
    }
    fn kind(&self) -> BusKind {
        BusKind::Sim
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With a bus number, received frames carry it (as a SocketCAN or
    /// simulated bus's do); without, they are left as fed.
    #[test]
    fn received_frames_carry_the_bus_number_given() {
        let (a, b) = MemBus::pair();
        let mut b = b.with_bus_id(3);
        let mut a2 = a.clone();
        a2.send(&CanFrame::default()).unwrap();
        let f = b.try_recv().unwrap().unwrap();
        assert_eq!((f.bus, f.direction), (3, can_dir::RX));
        b.send(&CanFrame::default()).unwrap();
        let mut a = a;
        assert_eq!(a.try_recv().unwrap().unwrap().bus, 0, "no number: as fed");
    }

    #[test]
    fn a_pair_carries_frames_both_ways_in_order_marked_received() {
        let (mut a, mut b) = MemBus::pair();
        for id in [0x100, 0x101] {
            a.send(&CanFrame::new(id, &[1, 2])).unwrap();
        }
        b.send(&CanFrame::new(0x200, &[3])).unwrap();
        let got: Vec<_> = std::iter::from_fn(|| b.try_recv().unwrap()).collect();
        assert_eq!(got.iter().map(|f| f.id).collect::<Vec<_>>(), [0x100, 0x101]);
        assert!(got.iter().all(|f| f.direction == can_dir::RX));
        assert_eq!(a.recv_timeout(Duration::ZERO).unwrap().unwrap().id, 0x200);
        assert_eq!(a.try_recv().unwrap(), None);
    }

    #[test]
    fn injected_frames_are_received_and_sent_ones_taken() {
        let mut m = MemBus::new();
        m.inject(CanFrame::new(0x10, &[]));
        assert_eq!(m.try_recv().unwrap().unwrap().id, 0x10);
        m.send(&CanFrame::new(0x20, &[])).unwrap();
        m.send(&CanFrame::new(0x21, &[])).unwrap();
        assert_eq!(m.take_sent().len(), 2);
        assert!(m.take_sent().is_empty());
        m.send(&CanFrame::new(0x22, &[])).unwrap();
        m.clear_sent();
        assert!(m.take_sent().is_empty());
    }

    #[test]
    fn drain_takes_at_most_the_buffer_and_leaves_the_rest_in_order() {
        let mut m = MemBus::new();
        for id in 0..5 {
            m.inject(CanFrame::new(id, &[]));
        }
        let mut buf = [CanFrame::default(); 3];
        let d = super::super::drain(&mut m, &mut buf);
        assert_eq!((d.frames, d.error), (3, false));
        assert_eq!(buf.map(|f| f.id), [0, 1, 2]);
        let d = super::super::drain(&mut m, &mut buf);
        assert_eq!((d.frames, d.error), (2, false));
        assert_eq!([buf[0].id, buf[1].id], [3, 4]);
        assert_eq!(super::super::drain(&mut m, &mut buf).frames, 0);
    }

    /// Filtered for a role, the in-memory bus hands over the role's ids
    /// only, in order, and drops the rest unseen (a foreign id, an extended
    /// frame numbered like a grip id, a remote frame, the other role's
    /// message), as SocketCAN's kernel filter and the simulated bus do.
    #[test]
    fn a_role_filter_drops_foreign_frames_and_keeps_the_roles_ids() {
        use crate::can::protocol::{
            DRIVER_DEMAND, MOTOR_STATUS, Role, TORQUE_COMMAND, VEHICLE_SPEED, WHEEL_SPEEDS,
        };
        use grip_msgs::can_flags;
        let flagged = |id, flags| {
            let mut f = CanFrame::new(id, &[0; 8]);
            f.flags = flags;
            f
        };
        let mut m = MemBus::new().with_rx_filter(RxFilter::Role(Role::Tcs));
        for f in [
            CanFrame::new(0x7FF, &[1; 8]),
            CanFrame::new(WHEEL_SPEEDS.id, &[2; 8]),
            flagged(0x1ABC_DEF0, can_flags::EXTENDED),
            flagged(MOTOR_STATUS.id, can_flags::EXTENDED),
            flagged(MOTOR_STATUS.id, can_flags::RTR),
            CanFrame::new(TORQUE_COMMAND.id, &[3; 8]),
            CanFrame::new(MOTOR_STATUS.id, &[4; 8]),
            CanFrame::new(VEHICLE_SPEED.id, &[5; 8]),
            CanFrame::new(0x5A5, &[6; 8]),
            CanFrame::new(DRIVER_DEMAND.id, &[7; 8]),
            CanFrame::new(0x7FF, &[8; 8]),
        ] {
            m.inject(f);
        }
        let got: Vec<_> = std::iter::from_fn(|| m.try_recv().unwrap()).collect();
        assert_eq!(
            got.iter().map(|f| (f.id, f.data[0])).collect::<Vec<_>>(),
            [
                (WHEEL_SPEEDS.id, 2),
                (MOTOR_STATUS.id, 4),
                (VEHICLE_SPEED.id, 5),
                (DRIVER_DEMAND.id, 7)
            ]
        );
        assert!(
            m.rx.borrow().is_empty(),
            "the rest dropped, not left queued"
        );
        // the inverter's bus: the command only
        let mut inv = MemBus::new().with_rx_filter(RxFilter::Role(Role::Inverter));
        for id in [0x7FF, WHEEL_SPEEDS.id, TORQUE_COMMAND.id, 0x101] {
            inv.inject(CanFrame::new(id, &[0; 8]));
        }
        assert_eq!(
            inv.recv_timeout(Duration::ZERO).unwrap().map(|f| f.id),
            Some(TORQUE_COMMAND.id)
        );
        assert_eq!(inv.try_recv().unwrap(), None);
        // unfiltered (the default, RxFilter::All): everything
        let mut all = MemBus::new();
        all.inject(CanFrame::new(0x7FF, &[]));
        all.inject(flagged(0x1ABC_DEF0, can_flags::EXTENDED));
        assert_eq!(all.try_recv().unwrap().map(|f| f.id), Some(0x7FF));
        assert_eq!(all.try_recv().unwrap().map(|f| f.id), Some(0x1ABC_DEF0));
    }

    #[test]
    fn a_late_delivery_advances_the_clock_once_when_the_frame_is_taken() {
        use crate::clock::Clock;
        let clock = ManualClock::new(1_000);
        let mut m = MemBus::new();
        m.deliver_late(&clock, 500);
        assert_eq!(m.try_recv().unwrap(), None);
        assert_eq!(clock.now_ns(), 1_000, "no frame, no delay");
        m.inject(CanFrame::new(0x10, &[]));
        m.inject(CanFrame::new(0x11, &[]));
        assert!(m.try_recv().unwrap().is_some());
        assert_eq!(clock.now_ns(), 1_500);
        assert!(m.try_recv().unwrap().is_some());
        assert_eq!(clock.now_ns(), 1_500, "only the next frame is late");
    }
}
