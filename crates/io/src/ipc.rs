//! iceoryx2 ports: node creation with stale-resource cleanup, typed
//! publishers and subscribers, dead-peer detection. Timed waits only.
//!
//! All iceoryx2 quality-of-service choices live in [`qos`].

use core::fmt::Debug;
use core::marker::PhantomData;

use iceoryx2::node::NodeView;
use iceoryx2::port::publisher::Publisher as IoxPublisher;
use iceoryx2::port::subscriber::Subscriber as IoxSubscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

/// The iceoryx2 service flavour grip uses: inter-process, shared memory.
pub type Svc = ipc::Service;

/// Service and port limits, in one place. Every process opens a topic with
/// the same values (iceoryx2 refuses an open that asks for more than the
/// creator configured).
pub mod qos {
    /// Limits of one publish-subscribe topic.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct TopicQos {
        /// Publishers the service admits.
        pub max_publishers: usize,
        /// Subscribers the service admits.
        pub max_subscribers: usize,
        /// Nodes that may open the service.
        pub max_nodes: usize,
        /// Largest subscriber buffer (the recorder's depth).
        pub max_buffer: usize,
        /// Samples a late subscriber gets on connecting.
        pub history: usize,
    }

    /// Default: a 1 kHz topic; 1024 samples = 1 s of slack for the recorder.
    pub const DEFAULT: TopicQos = TopicQos {
        max_publishers: 4,
        max_subscribers: 8,
        max_nodes: 16,
        max_buffer: 1024,
        history: 1,
    };
    /// Audio blocks are 8 KiB; 64 blocks ≈ 6 s at 4096 samples / 44.1 kHz.
    pub const AUDIO: TopicQos = TopicQos {
        max_buffer: 64,
        ..DEFAULT
    };
    /// Simulated CAN bus: every participant publishes and subscribes; 3
    /// messages per ms plus slow ones, 1024 frames ≈ 300 ms of slack.
    pub const SIM_BUS: TopicQos = TopicQos {
        max_publishers: 8,
        max_subscribers: 8,
        max_nodes: 16,
        max_buffer: 1024,
        history: 0,
    };
    /// The CAN log (every frame on the bus, ~3.2 kHz in a drive): 4096
    /// frames ≈ 1.3 s of slack for the recorder, as a 1 kHz topic has with
    /// [`DEFAULT`].
    pub const CAN_LOG: TopicQos = TopicQos {
        max_buffer: 4096,
        ..DEFAULT
    };
    /// Subscriber buffer of a "latest value wins" subscriber.
    pub const LATEST_BUFFER: usize = 1;
    /// Listeners/notifiers of the sim-bus wake-up event.
    pub const SIM_BUS_EVENT_PORTS: usize = 8;

    /// QoS for a topic name (see `grip_msgs::topics`).
    pub fn for_topic(topic: &str) -> TopicQos {
        if topic == grip_msgs::topics::AUDIO {
            AUDIO
        } else if topic == grip_msgs::topics::CAN_LOG {
            CAN_LOG
        } else if topic.starts_with(grip_msgs::topics::SIM_BUS_PREFIX) {
            SIM_BUS
        } else {
            DEFAULT
        }
    }
}

/// Environment variable naming the grip instance: concurrent drives (and
/// tests running in parallel) set a different value each, so their iceoryx2
/// services, nodes and simulated CAN buses never meet. Unset or empty: the
/// production namespace (iceoryx2's default file prefix).
pub const INSTANCE_ENV: &str = "GRIP_INSTANCE";

/// The iceoryx2 configuration this process uses: iceoryx2's global
/// configuration, with the file prefix `grip_<instance>_` when
/// [`INSTANCE_ENV`] is set. Read once per process.
pub fn iox_config() -> Result<&'static Config, IpcError> {
    static CONFIG: std::sync::OnceLock<Result<Config, String>> = std::sync::OnceLock::new();
    let cfg = CONFIG.get_or_init(|| {
        let mut cfg = global_config_quietly();
        match std::env::var(INSTANCE_ENV) {
            Ok(inst) if !inst.is_empty() => {
                let valid = inst.len() <= 64
                    && inst
                        .bytes()
                        .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_');
                if !valid {
                    return Err(format!(
                        "{INSTANCE_ENV}={inst:?}: use at most 64 characters of [A-Za-z0-9_-]"
                    ));
                }
                let prefix = format!("grip_{inst}_");
                cfg.global.prefix = FileName::new(prefix.as_bytes())
                    .map_err(|e| format!("{INSTANCE_ENV}={inst:?}: {e:?}"))?;
            }
            _ => {}
        }
        Ok(cfg)
    });
    cfg.as_ref().map_err(|reason| IpcError::Name {
        name: INSTANCE_ENV.into(),
        reason: reason.clone(),
    })
}

/// Where iceoryx2 looks for its configuration file, in its order: the
/// working directory's `config/`, the user's `~/.config/iceoryx2/` (home
/// from the password database, as iceoryx2 reads it, not `HOME`), `/etc`.
fn iox_config_files() -> Vec<std::path::PathBuf> {
    let mut v = vec![std::path::PathBuf::from("config/iceoryx2.toml")];
    if let Some(home) = passwd_home() {
        v.push(home.join(".config/iceoryx2/iceoryx2.toml"));
    }
    v.push("/etc/iceoryx2/iceoryx2.toml".into());
    v
}

/// The calling user's home directory from the password database.
fn passwd_home() -> Option<std::path::PathBuf> {
    use std::os::unix::ffi::OsStrExt;
    let mut buf = vec![0 as libc::c_char; 4096];
    // SAFETY: an all-zero passwd is a valid value to be filled in.
    let mut pw: libc::passwd = unsafe { core::mem::zeroed() };
    let mut out: *mut libc::passwd = core::ptr::null_mut();
    // SAFETY: getpwuid_r writes into `pw` and `buf` (whose length it is
    // given) and sets `out` to `&pw` or null; nothing is kept past the call
    // but the copied bytes below.
    let rc = unsafe {
        libc::getpwuid_r(
            libc::getuid(),
            &mut pw,
            buf.as_mut_ptr(),
            buf.len(),
            &mut out,
        )
    };
    if rc != 0 || out.is_null() || pw.pw_dir.is_null() {
        return None;
    }
    // SAFETY: pw_dir points at a NUL-terminated string inside `buf`.
    let dir = unsafe { core::ffi::CStr::from_ptr(pw.pw_dir) };
    Some(std::ffi::OsStr::from_bytes(dir.to_bytes()).into())
}

/// iceoryx2's global configuration, looked up without its warning "No
/// config file was loaded, a config with default values will be used":
/// grip's normal case (it ships no iceoryx2.toml), which printed a
/// two-line warning into every service's journal at every start. The
/// lookup runs under iceoryx2's Error level (`IOX2_LOG_LEVEL` still wins),
/// then the level is Warn again. What iceoryx2 would have warned of that
/// matters is said through `tracing`: each configuration file that exists
/// at one of its places but cannot be read (iceoryx2 skips it), in its
/// order, up to the first that reads (the one in use).
fn global_config_quietly() -> Config {
    use std::os::unix::ffi::OsStrExt;
    set_log_level_from_env_or(LogLevel::Error);
    let cfg = Config::global_config().clone();
    for f in iox_config_files().into_iter().filter(|f| f.is_file()) {
        let read = FilePath::new(f.as_os_str().as_bytes())
            .map_err(|e| format!("{e:?}"))
            .and_then(|p| Config::from_file(&p).map_err(|e| format!("{e:?}")));
        match read {
            Ok(_) => break,
            Err(reason) => tracing::warn!(
                file = %f.display(),
                reason,
                "an iceoryx2 configuration file that cannot be read: iceoryx2 skips it"
            ),
        }
    }
    set_log_level_from_env_or(LogLevel::Warn);
    cfg
}

/// Errors of the iceoryx2 adapters.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    /// Invalid node or service name.
    #[error("invalid iceoryx2 name {name:?}: {reason}")]
    Name {
        /// The name.
        name: String,
        /// Why.
        reason: String,
    },
    /// Node creation failed.
    #[error("cannot create iceoryx2 node {name:?}: {reason}")]
    Node {
        /// Node name.
        name: String,
        /// iceoryx2's error.
        reason: String,
    },
    /// Opening or creating a service failed (e.g. type or QoS mismatch with
    /// the process that created it).
    #[error("cannot open iceoryx2 service {topic:?} for {type_name}: {reason}")]
    Service {
        /// Topic.
        topic: String,
        /// Payload type.
        type_name: &'static str,
        /// iceoryx2's error.
        reason: String,
    },
    /// Creating a port failed.
    #[error("cannot create {kind} on {topic:?}: {reason}")]
    Port {
        /// "publisher", "subscriber", ...
        kind: &'static str,
        /// Topic.
        topic: String,
        /// iceoryx2's error.
        reason: String,
    },
    /// Sending failed.
    #[error("send on {topic:?} failed: {reason}")]
    Send {
        /// Topic.
        topic: &'static str,
        /// iceoryx2's error (static to stay allocation-free).
        reason: &'static str,
    },
    /// Receiving failed.
    #[error("receive on {topic:?} failed: {reason}")]
    Receive {
        /// Topic.
        topic: &'static str,
        /// Why.
        reason: &'static str,
    },
}

fn leak_topic(topic: &str) -> &'static str {
    // topics are a handful of start-up constants; leaking keeps the hot-path
    // errors allocation-free without lifetimes on every port.
    Box::leak(topic.to_owned().into_boxed_str())
}

/// Result of cleaning up the resources of dead nodes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CleanupReport {
    /// Dead nodes found.
    pub dead_found: u64,
    /// Dead nodes whose resources were removed.
    pub cleaned: u64,
    /// Dead nodes that could not be cleaned (permissions, another cleaner).
    pub failed: u64,
}

/// Finds nodes whose process died (e.g. `kill -9`) and removes their
/// stale shared memory and registrations (`NodeState::Dead` →
/// `DeadNodeView::try_remove_stale_resources`).
pub fn cleanup_dead_nodes() -> CleanupReport {
    let mut rep = CleanupReport::default();
    let Ok(config) = iox_config() else {
        return rep;
    };
    let res = Node::<Svc>::list(config, |state| {
        if let NodeState::<Svc>::Dead(view) = state {
            rep.dead_found += 1;
            let pid = view.details().as_ref().map(|d| d.executable().to_string());
            match view.try_remove_stale_resources() {
                Ok(()) => {
                    rep.cleaned += 1;
                    tracing::warn!(executable = ?pid, "removed stale iceoryx2 resources of a dead node");
                }
                Err(e) => {
                    rep.failed += 1;
                    tracing::warn!(executable = ?pid, error = ?e, "could not remove resources of a dead node");
                }
            }
        }
        CallbackProgression::Continue
    });
    if let Err(e) = res {
        tracing::warn!(error = ?e, "could not list iceoryx2 nodes");
    }
    rep
}

/// Peers of a topic, by the liveness of their nodes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PeerReport {
    /// Nodes attached to the service whose process is alive (includes us).
    pub alive: usize,
    /// Nodes attached to the service whose process died.
    pub dead: usize,
    /// Publishers currently registered (dead ones count until cleaned up).
    pub publishers: usize,
    /// Subscribers currently registered.
    pub subscribers: usize,
}

/// A grip process's iceoryx2 node. Creating it first removes the resources
/// that dead nodes (crashed processes) left behind.
pub struct IpcNode {
    node: Node<Svc>,
    name: String,
}

impl Debug for IpcNode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("IpcNode").field("name", &self.name).finish()
    }
}

impl IpcNode {
    /// Creates a node named `name` (see `grip_msgs::topics::node`). Sets
    /// iceoryx2's own log level to Warn unless `IOX2_LOG_LEVEL` is set, and
    /// cleans up dead nodes first.
    pub fn create(name: &str) -> Result<Self, IpcError> {
        set_log_level_from_env_or(LogLevel::Warn);
        let rep = cleanup_dead_nodes();
        if rep.dead_found > 0 {
            tracing::warn!(?rep, "dead iceoryx2 nodes found at start-up");
        }
        let node_name: NodeName = name.try_into().map_err(|e| IpcError::Name {
            name: name.into(),
            reason: format!("{e:?}"),
        })?;
        let config = iox_config()?;
        let node = NodeBuilder::new()
            .config(config)
            .name(&node_name)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Svc>()
            .map_err(|e| IpcError::Node {
                name: name.into(),
                reason: format!("{e:?}"),
            })?;
        Ok(Self {
            node,
            name: name.into(),
        })
    }

    /// The node's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The underlying iceoryx2 node (for services grip does not wrap).
    pub fn raw(&self) -> &Node<Svc> {
        &self.node
    }

    /// Removes resources of dead nodes (see [`cleanup_dead_nodes`]).
    pub fn cleanup_dead_nodes(&self) -> CleanupReport {
        cleanup_dead_nodes()
    }

    fn service<T: ZeroCopySend + Debug + Copy + 'static>(
        &self,
        topic: &str,
    ) -> Result<PubSubFactory<Svc, T, ()>, IpcError> {
        let q = qos::for_topic(topic);
        let name: ServiceName = topic.try_into().map_err(|e| IpcError::Name {
            name: topic.into(),
            reason: format!("{e:?}"),
        })?;
        self.node
            .service_builder(&name)
            .publish_subscribe::<T>()
            .max_publishers(q.max_publishers)
            .max_subscribers(q.max_subscribers)
            .max_nodes(q.max_nodes)
            .subscriber_max_buffer_size(q.max_buffer)
            .history_size(q.history)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|e| IpcError::Service {
                topic: topic.into(),
                // SAFETY: reading a type name has no preconditions beyond
                // the trait's layout contract, which the derive upholds.
                type_name: unsafe { <T as ZeroCopySend>::type_name() },
                reason: format!("{e:?}"),
            })
    }

    /// A publisher of `T` on `topic`.
    pub fn publisher<T: ZeroCopySend + Debug + Copy + 'static>(
        &self,
        topic: &str,
    ) -> Result<Publisher<T>, IpcError> {
        let service = self.service::<T>(topic)?;
        let port = service
            .publisher_builder()
            .create()
            .map_err(|e| IpcError::Port {
                kind: "publisher",
                topic: topic.into(),
                reason: format!("{e:?}"),
            })?;
        Ok(Publisher {
            port,
            service,
            topic: leak_topic(topic),
        })
    }

    /// A subscriber of `T` on `topic`. [`SubscriberMode::Latest`] keeps only
    /// the newest sample (control inputs); [`SubscriberMode::Deep`] keeps
    /// the topic's full buffer and asks for its history (the recorder);
    /// [`SubscriberMode::Buffered`] keeps the number of samples it names.
    pub fn subscriber<T: ZeroCopySend + Debug + Copy + 'static>(
        &self,
        topic: &str,
        mode: SubscriberMode,
    ) -> Result<Subscriber<T>, IpcError> {
        let service = self.service::<T>(topic)?;
        let q = qos::for_topic(topic);
        let builder = service.subscriber_builder();
        let builder = match mode {
            SubscriberMode::Latest => builder.buffer_size(qos::LATEST_BUFFER),
            SubscriberMode::Deep => builder.buffer_size(q.max_buffer),
            SubscriberMode::Buffered(n) => builder.buffer_size(n.clamp(1, q.max_buffer)),
        };
        let port = builder.create().map_err(|e| IpcError::Port {
            kind: "subscriber",
            topic: topic.into(),
            reason: format!("{e:?}"),
        })?;
        Ok(Subscriber {
            port,
            service,
            topic: leak_topic(topic),
            _t: PhantomData,
        })
    }
}

impl IpcNode {
    /// Opens (or creates) `topic`'s service only to watch its peers: no
    /// port, nothing sent or received. [`TopicWatch::peers`] is the same
    /// report as a port's, for a thread that owns no port (the recorder
    /// asks from a thread of its own, since listing a topic's nodes reads
    /// and parses every node's details and is not cheap).
    pub fn watch<T: ZeroCopySend + Debug + Copy + 'static>(
        &self,
        topic: &str,
    ) -> Result<TopicWatch<T>, IpcError> {
        Ok(TopicWatch {
            service: self.service::<T>(topic)?,
            topic: leak_topic(topic),
        })
    }
}

/// A topic's service held open without a port ([`IpcNode::watch`]).
pub struct TopicWatch<T: ZeroCopySend + Debug + Copy + 'static> {
    service: PubSubFactory<Svc, T, ()>,
    topic: &'static str,
}

impl<T: ZeroCopySend + Debug + Copy + 'static> Debug for TopicWatch<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("TopicWatch")
            .field("topic", &self.topic)
            .finish()
    }
}

impl<T: ZeroCopySend + Debug + Copy + 'static> TopicWatch<T> {
    /// The topic.
    pub fn topic(&self) -> &'static str {
        self.topic
    }
    /// Liveness of the topic's peers (iterates the nodes: not cheap).
    pub fn peers(&self) -> PeerReport {
        peers(&self.service)
    }
}

/// How a subscriber buffers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SubscriberMode {
    /// Buffer of one: a read returns the newest sample (older ones are overwritten).
    Latest,
    /// The topic's full buffer (`qos::for_topic(..).max_buffer`).
    Deep,
    /// A buffer of this many samples (at most the topic's `max_buffer`),
    /// read oldest first: a stream in which every sample counts (the road
    /// estimates the loop queues by place). When it is full the oldest
    /// unread sample is overwritten (safe overflow).
    Buffered(usize),
}

fn peers<T: ZeroCopySend + Debug + Copy + 'static>(s: &PubSubFactory<Svc, T, ()>) -> PeerReport {
    let mut rep = PeerReport::default();
    let _ = s.nodes(|state| {
        match state {
            NodeState::Alive(_) => rep.alive += 1,
            NodeState::Dead(_) => rep.dead += 1,
            _ => {}
        }
        CallbackProgression::Continue
    });
    let dc = s.dynamic_config();
    rep.publishers = dc.number_of_publishers();
    rep.subscribers = dc.number_of_subscribers();
    rep
}

/// Typed publisher. `publish` copies the value into a loaned shared-memory
/// sample; allocation-free.
pub struct Publisher<T: ZeroCopySend + Debug + Copy + 'static> {
    port: IoxPublisher<Svc, T, ()>,
    service: PubSubFactory<Svc, T, ()>,
    topic: &'static str,
}

impl<T: ZeroCopySend + Debug + Copy + 'static> Debug for Publisher<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Publisher")
            .field("topic", &self.topic)
            .finish()
    }
}

impl<T: ZeroCopySend + Debug + Copy + 'static> Publisher<T> {
    /// Publishes a copy of `value`; returns how many subscribers got it.
    pub fn publish(&self, value: &T) -> Result<usize, IpcError> {
        let sample = self.port.loan_uninit().map_err(|_| IpcError::Send {
            topic: self.topic,
            reason: "loan failed (all samples in use)",
        })?;
        let sample = sample.write_payload(*value);
        sample.send().map_err(|_| IpcError::Send {
            topic: self.topic,
            reason: "send failed",
        })
    }
    /// The topic.
    pub fn topic(&self) -> &'static str {
        self.topic
    }
    /// Liveness of the topic's peers (not for the hot path: iterates nodes).
    pub fn peers(&self) -> PeerReport {
        peers(&self.service)
    }
    pub(crate) fn id(&self) -> iceoryx2::identifiers::UniquePublisherId {
        self.port.id()
    }
}

/// Typed subscriber; reads copy the sample out and release it at once.
pub struct Subscriber<T: ZeroCopySend + Debug + Copy + 'static> {
    port: IoxSubscriber<Svc, T, ()>,
    service: PubSubFactory<Svc, T, ()>,
    topic: &'static str,
    _t: PhantomData<T>,
}

impl<T: ZeroCopySend + Debug + Copy + 'static> Debug for Subscriber<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Subscriber")
            .field("topic", &self.topic)
            .finish()
    }
}

impl<T: ZeroCopySend + Debug + Copy + 'static> Subscriber<T> {
    /// The oldest unread sample, if any.
    pub fn recv(&self) -> Result<Option<T>, IpcError> {
        match self.port.receive() {
            Ok(Some(s)) => Ok(Some(*s)),
            Ok(None) => Ok(None),
            Err(_) => Err(IpcError::Receive {
                topic: self.topic,
                reason: "receive failed",
            }),
        }
    }
    /// Drains the buffer and returns the newest sample, if any arrived.
    pub fn latest(&self) -> Result<Option<T>, IpcError> {
        let mut last = None;
        while let Some(v) = self.recv()? {
            last = Some(v);
        }
        Ok(last)
    }
    /// Calls `f` for every unread sample in order; returns how many.
    pub fn drain(&self, mut f: impl FnMut(&T)) -> Result<usize, IpcError> {
        let mut n = 0;
        loop {
            match self.port.receive() {
                Ok(Some(s)) => {
                    f(&s);
                    n += 1;
                }
                Ok(None) => return Ok(n),
                Err(_) => {
                    return Err(IpcError::Receive {
                        topic: self.topic,
                        reason: "receive failed",
                    });
                }
            }
        }
    }
    /// Like [`recv`](Self::recv) but skips samples from the publisher `own`
    /// (used by the simulated bus).
    pub(crate) fn recv_not_from(
        &self,
        own: iceoryx2::identifiers::UniquePublisherId,
    ) -> Result<Option<T>, IpcError> {
        loop {
            match self.port.receive() {
                Ok(Some(s)) => {
                    if s.header().publisher_id() != own {
                        return Ok(Some(*s));
                    }
                }
                Ok(None) => return Ok(None),
                Err(_) => {
                    return Err(IpcError::Receive {
                        topic: self.topic,
                        reason: "receive failed",
                    });
                }
            }
        }
    }
    /// The topic.
    pub fn topic(&self) -> &'static str {
        self.topic
    }
    /// Liveness of the topic's peers: a `dead` count > 0 means a publisher's
    /// or subscriber's process died; call [`cleanup_dead_nodes`].
    pub fn peers(&self) -> PeerReport {
        peers(&self.service)
    }
}
