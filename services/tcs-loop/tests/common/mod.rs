//! Test doubles: an in-memory CAN bus (preallocated queues; `send` and
//! `try_recv` allocate nothing while under capacity) and recording sinks.

#![allow(dead_code)]

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use std::time::Duration;

use grip_io::can::{BusKind, CanBus, CanError};
use grip_msgs::{CanFrame, CycleRecord, RoadEstimate, can_dir};
use grip_tcs_loop::{RecordSink, RoadSource};

pub type Queue = Rc<RefCell<VecDeque<CanFrame>>>;

pub fn queue() -> Queue {
    Rc::new(RefCell::new(VecDeque::with_capacity(1 << 16)))
}

/// One participant: reads `rx`, writes `tx`.
#[derive(Clone)]
pub struct MemBus {
    pub rx: Queue,
    pub tx: Queue,
}

impl MemBus {
    /// A participant whose queues the test feeds and reads directly.
    pub fn new() -> Self {
        Self {
            rx: queue(),
            tx: queue(),
        }
    }
    /// Two participants wired to each other.
    pub fn pair() -> (Self, Self) {
        let (a, b) = (queue(), queue());
        (
            Self {
                rx: a.clone(),
                tx: b.clone(),
            },
            Self { rx: b, tx: a },
        )
    }
    pub fn inject(&self, f: CanFrame) {
        self.rx.borrow_mut().push_back(f);
    }
    pub fn take_sent(&self) -> Vec<CanFrame> {
        self.tx.borrow_mut().drain(..).collect()
    }
    pub fn clear_sent(&self) {
        self.tx.borrow_mut().clear();
    }
}

impl CanBus for MemBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), CanError> {
        self.tx.borrow_mut().push_back(*frame);
        Ok(())
    }
    fn try_recv(&mut self) -> Result<Option<CanFrame>, CanError> {
        Ok(self.rx.borrow_mut().pop_front().map(|mut f| {
            f.direction = can_dir::RX;
            f
        }))
    }
    fn recv_timeout(&mut self, _: Duration) -> Result<Option<CanFrame>, CanError> {
        self.try_recv()
    }
    fn kind(&self) -> BusKind {
        BusKind::Sim
    }
}

/// Keeps the last record and counts CAN log copies (allocation-free).
#[derive(Default)]
pub struct LastSink {
    pub last: Option<CycleRecord>,
    pub records: u64,
    pub can_rx: u64,
    pub can_tx: u64,
    pub can_rejected: u64,
}

impl RecordSink for LastSink {
    fn cycle(&mut self, rec: &CycleRecord) {
        self.last = Some(*rec);
        self.records += 1;
    }
    fn can(&mut self, f: &CanFrame) {
        if f.direction == can_dir::TX {
            self.can_tx += 1;
        } else {
            self.can_rx += 1;
        }
        if f.flags & grip_msgs::can_flags::E2E_REJECTED != 0 {
            self.can_rejected += 1;
        }
    }
}

/// A road source the test sets.
#[derive(Default)]
pub struct SetRoad {
    pub next: Option<RoadEstimate>,
}

impl RoadSource for SetRoad {
    fn poll_latest(&mut self) -> Option<RoadEstimate> {
        self.next.take()
    }
}
