//! Simulated CAN bus over iceoryx2: one publish-subscribe service per bus
//! (`grip/canbus/<name>`, payload `CanFrame`), every participant publishes
//! to it and subscribes from it and drops its own frames (by publisher id);
//! an event service `grip/canbus/<name>/wake` wakes waiting receivers.
//! Like a real bus it broadcasts; unlike one it has no arbitration delay and
//! a slow reader loses its oldest frames when its 1024-frame buffer overflows.
//! A participant's [`RxFilter`] is applied on receipt, as the kernel applies
//! it to a SocketCAN bus: a frame it does not pass is dropped unseen.
//! A frame is stamped (CLOCK_MONOTONIC) when it is published, the time it
//! reaches every receiver on a bus without delay, as SocketCAN's kernel
//! stamps a frame when it arrives: a receiver that reads it later (a stall)
//! still sees when it came.

use core::time::Duration;

use grip_msgs::{CanFrame, can_dir, topics};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;

use super::{BusKind, CanBus, CanError, RxFilter};
use crate::clock::monotonic_now_ns;
use crate::ipc::{IpcError, IpcNode, Publisher, Subscriber, SubscriberMode, Svc, qos};

/// A participant on a simulated bus.
pub struct SimBus {
    publisher: Publisher<CanFrame>,
    subscriber: Subscriber<CanFrame>,
    notifier: Notifier<Svc>,
    listener: Listener<Svc>,
    bus_id: u8,
    name: String,
    rx: RxFilter,
}

impl core::fmt::Debug for SimBus {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SimBus").field("name", &self.name).finish()
    }
}

impl SimBus {
    /// Joins (creating if needed) the simulated bus `name`, receiving every
    /// frame the others send ([`RxFilter::All`]; see [`Self::with_rx_filter`]).
    pub fn open(node: &IpcNode, name: &str, bus_id: u8) -> Result<Self, CanError> {
        let topic = format!("{}{}", topics::SIM_BUS_PREFIX, name);
        let publisher = node.publisher::<CanFrame>(&topic)?;
        let subscriber = node.subscriber::<CanFrame>(&topic, SubscriberMode::Deep)?;
        let ev_name = format!("{topic}{}", topics::SIM_BUS_EVENT_SUFFIX);
        let sname: ServiceName = ev_name.as_str().try_into().map_err(|e| IpcError::Name {
            name: ev_name.clone(),
            reason: format!("{e:?}"),
        })?;
        let event = node
            .raw()
            .service_builder(&sname)
            .event()
            .max_notifiers(qos::SIM_BUS_EVENT_PORTS)
            .max_listeners(qos::SIM_BUS_EVENT_PORTS)
            .open_or_create()
            .map_err(|e| IpcError::Service {
                topic: ev_name.clone(),
                type_name: "event",
                reason: format!("{e:?}"),
            })?;
        let notifier = event
            .notifier_builder()
            .create()
            .map_err(|e| IpcError::Port {
                kind: "notifier",
                topic: ev_name.clone(),
                reason: format!("{e:?}"),
            })?;
        let listener = event
            .listener_builder()
            .create()
            .map_err(|e| IpcError::Port {
                kind: "listener",
                topic: ev_name.clone(),
                reason: format!("{e:?}"),
            })?;
        Ok(Self {
            publisher,
            subscriber,
            notifier,
            listener,
            bus_id,
            name: name.into(),
            rx: RxFilter::All,
        })
    }

    /// Receives only what `rx` lets through (also frames already waiting).
    pub fn with_rx_filter(mut self, rx: RxFilter) -> Self {
        self.rx = rx;
        self
    }

    /// What this participant receives.
    pub fn rx_filter(&self) -> RxFilter {
        self.rx
    }

    /// Bus name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Liveness of the bus participants (dead > 0: a peer process died).
    pub fn peers(&self) -> crate::ipc::PeerReport {
        self.subscriber.peers()
    }

    /// A received frame as its receiver sees it: its publish stamp kept.
    fn received(&self, mut f: CanFrame) -> CanFrame {
        f.direction = can_dir::RX;
        f.bus = self.bus_id;
        f
    }
}

impl CanBus for SimBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), CanError> {
        if frame.dlc > 8 {
            return Err(CanError::InvalidFrame {
                id: frame.id,
                dlc: frame.dlc,
            });
        }
        // stamped as it goes on the bus: every receiver's arrival time
        let mut f = *frame;
        f.stamp_ns = monotonic_now_ns();
        self.publisher.publish(&f)?;
        // wake-up is best effort: a receiver also finds the frame by polling
        let _ = self.notifier.notify();
        Ok(())
    }

    /// The next frame from another participant that the filter passes;
    /// frames it does not pass are dropped on the way (at most the
    /// subscriber's buffer of them in one call).
    fn try_recv(&mut self) -> Result<Option<CanFrame>, CanError> {
        while let Some(f) = self.subscriber.recv_not_from(self.publisher.id())? {
            if self.rx.accepts(&f) {
                return Ok(Some(self.received(f)));
            }
        }
        Ok(None)
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, CanError> {
        let deadline = super::deadline_after(timeout);
        loop {
            if let Some(f) = self.try_recv()? {
                return Ok(Some(f));
            }
            let now = monotonic_now_ns();
            if now >= deadline {
                return Ok(None);
            }
            // bounded wait: never hangs if the sender died
            self.listener
                .timed_wait(|_| {}, Duration::from_nanos(deadline - now))
                .map_err(|_| {
                    CanError::Ipc(IpcError::Receive {
                        topic: "sim-bus wake event",
                        reason: "listener wait failed",
                    })
                })?;
        }
    }

    fn kind(&self) -> BusKind {
        BusKind::Sim
    }
}
