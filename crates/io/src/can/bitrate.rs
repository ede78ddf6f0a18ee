//! The bit rate the bus load is judged at: the interface's own, as the
//! kernel reports it (`ip link set can0 type can bitrate N` on a car), where
//! there is one; else the DBC's `Baudrate`; else grip's bus,
//! [`DEFAULT_BITRATE`] (`crates/io/README.md`, "Bus load").
//!
//! [`read_interface_bitrate`] asks the kernel (netlink, `IFLA_CAN_BITTIMING`,
//! through `socketcan::CanInterface::bit_rate`); [`choose_bitrate`] is the
//! decision, a pure function, with the warnings to log. Neither ever fails:
//! a netlink error is a warning and the DBC's rate (or the assumed one) is
//! used, as before the interface was read.

use super::{CanBusConfig, Transport, interface_exists};
use crate::can::protocol::DEFAULT_BITRATE;

/// What the kernel says about an interface's bit rate.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum InterfaceBitrate {
    /// The interface runs at this many bit/s (a CAN controller whose bit
    /// timing is set).
    Reported(u32),
    /// The interface reports none: a virtual one (`vcan`, `vxcan`), or a
    /// controller whose bit rate is not set yet.
    NotReported,
    /// No interface of that name (yet): nothing to read (`transport =
    /// "auto"` then takes the simulated bus; `"socketcan"` fails to open it).
    Absent,
    /// `transport = "sim"`: the simulated bus has no bit rate.
    Simulated,
    /// Asking failed (netlink refused or answered nonsense): why.
    Failed(String),
}

/// Where the bit rate used comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BitrateSource {
    /// The interface of this name reports it.
    Interface(String),
    /// The DBC's `Baudrate`.
    Dbc,
    /// Neither: [`DEFAULT_BITRATE`], grip's bus.
    Assumed,
}

/// The bit rate the bus load is judged at, where it comes from, and what to
/// warn about ([`choose_bitrate`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BitrateChoice {
    /// Bit/s.
    pub bitrate: u32,
    /// Where it comes from.
    pub source: BitrateSource,
    /// For the start-up line: which rate was used and why, e.g. `1000000
    /// bit/s read from can0` or `the DBC's Baudrate, 500000 bit/s (vcan0
    /// reports no bit rate: a virtual interface, or one whose bit rate is
    /// not set)`.
    pub note: String,
    /// Lines to log as warnings: the interface's rate differs from the
    /// DBC's; the interface's rate could not be read.
    pub warnings: Vec<String>,
}

/// Chooses the bit rate for the bus load of interface `iface`: what the
/// interface reports (`read`) wins, else the DBC's `Baudrate` (`dbc`), else
/// [`DEFAULT_BITRATE`]. Warns when the interface's rate differs from the
/// DBC's (naming both) and when it could not be read. Pure: no I/O.
pub fn choose_bitrate(iface: &str, read: &InterfaceBitrate, dbc: Option<u32>) -> BitrateChoice {
    let mut warnings = Vec::new();
    if let InterfaceBitrate::Reported(b) = *read
        && b > 0
    {
        if let Some(d) = dbc
            && d != b
        {
            warnings.push(format!(
                "CAN interface {iface} runs at {b} bit/s (read from the kernel), but the DBC's Baudrate says {d} bit/s: the bus load is judged at {iface}'s {b} bit/s; correct the DBC's Baudrate, or set {iface}'s bit rate (ip link set {iface} type can bitrate {d}, while it is down) if the DBC is right"
            ));
        }
        return BitrateChoice {
            bitrate: b,
            source: BitrateSource::Interface(iface.to_owned()),
            note: format!("{b} bit/s read from {iface}"),
            warnings,
        };
    }
    let why = match read {
        InterfaceBitrate::Reported(_) | InterfaceBitrate::NotReported => format!(
            "{iface} reports no bit rate: a virtual interface, or one whose bit rate is not set"
        ),
        InterfaceBitrate::Absent => format!("no interface {iface} to read it from"),
        InterfaceBitrate::Simulated => "the simulated bus has no bit rate".to_owned(),
        InterfaceBitrate::Failed(e) => {
            warnings.push(format!(
                "the bit rate of CAN interface {iface} could not be read ({e}): the bus load is judged at {}",
                match dbc {
                    Some(d) => format!("the DBC's Baudrate, {d} bit/s"),
                    None => format!("{DEFAULT_BITRATE} bit/s (assumed: no Baudrate in the DBC either)"),
                }
            ));
            format!("{iface}'s could not be read: {e}")
        }
    };
    match dbc {
        Some(d) => BitrateChoice {
            bitrate: d,
            source: BitrateSource::Dbc,
            note: format!("the DBC's Baudrate, {d} bit/s ({why})"),
            warnings,
        },
        None => BitrateChoice {
            bitrate: DEFAULT_BITRATE,
            source: BitrateSource::Assumed,
            note: format!("{DEFAULT_BITRATE} bit/s assumed (no Baudrate in the DBC; {why})"),
            warnings,
        },
    }
}

/// Asks the kernel at what bit rate `cfg`'s interface runs (one netlink
/// round trip, `RTM_GETLINK`; no privilege needed). Never fails: an error
/// comes back as [`InterfaceBitrate::Failed`]. A rate of 0 counts as none.
pub fn read_interface_bitrate(cfg: &CanBusConfig) -> InterfaceBitrate {
    if cfg.transport == Transport::Sim {
        return InterfaceBitrate::Simulated;
    }
    if !interface_exists(&cfg.interface) {
        return InterfaceBitrate::Absent;
    }
    match socketcan::CanInterface::open(&cfg.interface).and_then(|i| i.bit_rate()) {
        Ok(Some(b)) if b > 0 => InterfaceBitrate::Reported(b),
        Ok(_) => InterfaceBitrate::NotReported,
        Err(e) => InterfaceBitrate::Failed(e.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn choose(read: InterfaceBitrate, dbc: Option<u32>) -> BitrateChoice {
        choose_bitrate("can0", &read, dbc)
    }

    /// The interface's rate wins over the DBC's and over the assumed one;
    /// a DBC that agrees gives no warning.
    #[test]
    fn the_interfaces_rate_wins() {
        for dbc in [None, Some(1_000_000)] {
            let c = choose(InterfaceBitrate::Reported(1_000_000), dbc);
            assert_eq!(c.bitrate, 1_000_000);
            assert_eq!(c.source, BitrateSource::Interface("can0".into()));
            assert!(c.warnings.is_empty(), "{:?}", c.warnings);
            assert_eq!(c.note, "1000000 bit/s read from can0");
        }
        let c = choose(InterfaceBitrate::Reported(500_000), None);
        assert_eq!(c.bitrate, 500_000);
        assert!(c.warnings.is_empty());
    }

    /// An interface at another rate than the DBC's: the interface's is
    /// used, and one warning names both.
    #[test]
    fn a_dbc_that_disagrees_is_warned_about_naming_both() {
        let c = choose(InterfaceBitrate::Reported(500_000), Some(1_000_000));
        assert_eq!(c.bitrate, 500_000);
        assert_eq!(c.source, BitrateSource::Interface("can0".into()));
        assert_eq!(c.warnings.len(), 1);
        let w = &c.warnings[0];
        assert!(
            w.contains("can0 runs at 500000 bit/s") && w.contains("Baudrate says 1000000 bit/s"),
            "{w}"
        );
        let c = choose(InterfaceBitrate::Reported(1_000_000), Some(500_000));
        assert_eq!(c.bitrate, 1_000_000);
        assert_eq!(c.warnings.len(), 1);
    }

    /// No rate from the interface (vcan, rate not set, no interface, the
    /// simulated bus): today's behaviour, the DBC's, else 1 Mbit/s, and the
    /// note says why; no warning.
    #[test]
    fn without_the_interfaces_rate_the_dbcs_else_the_assumed() {
        for (read, why) in [
            (InterfaceBitrate::NotReported, "can0 reports no bit rate"),
            (InterfaceBitrate::Reported(0), "can0 reports no bit rate"),
            (InterfaceBitrate::Absent, "no interface can0"),
            (InterfaceBitrate::Simulated, "the simulated bus"),
        ] {
            let c = choose(read.clone(), Some(500_000));
            assert_eq!((c.bitrate, &c.source), (500_000, &BitrateSource::Dbc));
            assert!(
                c.note.contains("the DBC's Baudrate, 500000 bit/s"),
                "{}",
                c.note
            );
            assert!(c.note.contains(why), "{read:?}: {}", c.note);
            assert!(c.warnings.is_empty(), "{read:?}: {:?}", c.warnings);
            let c = choose(read.clone(), None);
            assert_eq!(
                (c.bitrate, &c.source),
                (DEFAULT_BITRATE, &BitrateSource::Assumed)
            );
            assert!(
                c.note.contains("assumed") && c.note.contains(why),
                "{}",
                c.note
            );
            assert!(c.warnings.is_empty());
        }
    }

    /// A netlink error is a warning and a fallback, never fatal.
    #[test]
    fn a_netlink_error_falls_back_with_a_warning() {
        let failed = InterfaceBitrate::Failed("netlink error: Operation not permitted".into());
        let c = choose(failed.clone(), Some(500_000));
        assert_eq!((c.bitrate, c.source), (500_000, BitrateSource::Dbc));
        assert_eq!(c.warnings.len(), 1);
        assert!(
            c.warnings[0].contains("could not be read (netlink error: Operation not permitted)")
                && c.warnings[0].contains("the DBC's Baudrate, 500000 bit/s"),
            "{}",
            c.warnings[0]
        );
        let c = choose(failed, None);
        assert_eq!(
            (c.bitrate, c.source),
            (DEFAULT_BITRATE, BitrateSource::Assumed)
        );
        assert_eq!(c.warnings.len(), 1);
        assert!(
            c.warnings[0].contains("1000000 bit/s (assumed"),
            "{}",
            c.warnings[0]
        );
    }

    /// The simulated transport never asks the kernel; an interface that
    /// does not exist is `Absent`.
    #[test]
    fn what_is_read_without_an_interface() {
        let sim = CanBusConfig {
            transport: Transport::Sim,
            ..CanBusConfig::default()
        };
        assert_eq!(read_interface_bitrate(&sim), InterfaceBitrate::Simulated);
        let none = CanBusConfig {
            transport: Transport::Socketcan,
            interface: "gripnone7".into(),
            ..CanBusConfig::default()
        };
        assert_eq!(read_interface_bitrate(&none), InterfaceBitrate::Absent);
    }
}
