//! Test doubles: an in-memory CAN bus with preallocated queues (no
//! allocation while under capacity), a truth recorder, and the shipped
//! configuration.

#![allow(dead_code)]

use std::cell::RefCell;
use std::collections::VecDeque;
use std::path::PathBuf;
use std::rc::Rc;
use std::time::Duration;

use grip_config::ConfigDir;
use grip_io::can::{BusKind, CanBus, CanError};
use grip_msgs::{CanFrame, GroundTruth, can_dir};
use grip_plant_sim::{PlantSim, PlantSimConfig, TruthSink};

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
    pub fn new() -> Self {
        Self {
            rx: queue(),
            tx: queue(),
        }
    }
    pub fn inject(&self, f: CanFrame) {
        self.rx.borrow_mut().push_back(f);
    }
    pub fn take_sent(&self) -> Vec<CanFrame> {
        self.tx.borrow_mut().drain(..).collect()
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

/// Keeps the last truth sample and counts them.
#[derive(Default)]
pub struct LastTruth {
    pub last: Option<GroundTruth>,
    pub n: u64,
}

impl TruthSink for LastTruth {
    fn truth(&mut self, g: &GroundTruth) {
        self.last = Some(*g);
        self.n += 1;
    }
}

pub fn config_dir() -> ConfigDir {
    ConfigDir::new(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config"))
}

/// A simulator of the shipped `scenario` with the shipped vehicle and sensors.
pub fn sim(cfg: &PlantSimConfig) -> PlantSim {
    let dir = config_dir();
    let roads = dir.roads().unwrap();
    let scenario = dir.scenario_with(&cfg.scenario, &roads).unwrap();
    let (vehicle, sensors) = dir.vehicle().unwrap();
    PlantSim::new(cfg, scenario, roads, &vehicle, &sensors).unwrap()
}
