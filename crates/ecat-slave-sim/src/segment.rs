//! A line of devices on one Ethernet port, the way a frame walks it: in through port 0 of
//! each device in turn, every device processing every datagram on the fly, back from the
//! last one through the forwarding path to the master. Faults are injected here.

use rtcnc_fieldbus::sim::ProbeSide;
use serde::Deserialize;

use crate::dio::DioTerminal;
use crate::drive::CspDrive;
use crate::esc::{Addressing, AlState, HOP_DELAY_NS, Slave};
use crate::frame::{
    Command, DatagramSpan, FrameError, WKC_LEN, datagrams, read_u16, read_u32, write_u16,
};

/// Largest number of datagrams in one frame the segment accepts.
pub const MAX_DATAGRAMS: usize = 64;

/// A fault put into the segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// Frames are lost at this rate (0 to 1), drawn from the segment's seeded generator.
    FrameLoss {
        /// Probability that a frame is lost.
        rate: f64,
    },
    /// A device drops to SAFE-OP with the error flag and this AL status code.
    FallToSafeOp {
        /// Position of the device in the segment (0 is the first).
        slave: usize,
        /// AL status code.
        code: u16,
    },
    /// A drive detects an internal fault with this CiA 402 error code (0x603F).
    DriveFault {
        /// Position of the device.
        slave: usize,
        /// Error code.
        error_code: u16,
    },
    /// The cable to the first device is pulled: no frame comes back.
    LinkDown,
    /// A device stops serving the process data (its logical datagrams pass it untouched,
    /// its working counter share goes missing) while it stays in OP and answers every
    /// other datagram, as one whose process data interface failed.
    ProcessDataLoss {
        /// Position of the device.
        slave: usize,
    },
}

/// A touch probe over a flat surface across one drive's travel, wired into drives' touch
/// probe 1 inputs and, optionally, into an I/O terminal's input (so the controller sees
/// its level). The probe is in contact while that drive's load stands at or beyond
/// `surface` (below it with `side = "below"`, the default; above it with `"above"`), in the
/// drive's own position units; each crossing is an edge at its instant (the load taken to
/// move linearly within a cycle), rising into contact, falling out of it.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeWire {
    /// Position in the segment of the drive whose load meets the surface.
    pub sensed: usize,
    /// Where the surface is (the sensed drive's joint units).
    pub surface: f64,
    /// Which side of the surface is in contact.
    #[serde(default)]
    pub side: ProbeSide,
    /// Positions of the drives whose touch probe 1 input the probe is wired to.
    pub drives: Vec<usize>,
    /// The I/O terminal input it is wired to: the terminal's position and the input bit.
    #[serde(default)]
    pub input: Option<ProbeInput>,
}

/// An I/O terminal's input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeInput {
    /// Position of the terminal in the segment.
    pub device: usize,
    /// Input bit (0 to 7).
    pub bit: u8,
}

impl ProbeWire {
    fn contact(&self, position: f64) -> bool {
        match self.side {
            ProbeSide::Below => position <= self.surface,
            ProbeSide::Above => position >= self.surface,
        }
    }
}

/// A request naming something the segment does not have.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SegmentError {
    /// No device at that position.
    #[error("no device at position {slave}: the segment has {count}")]
    NoSuchSlave {
        /// Position asked for.
        slave: usize,
        /// Devices present.
        count: usize,
    },
    /// The device has no such fault (e.g. a drive fault on an I/O terminal).
    #[error("device {slave} cannot take that fault")]
    NotApplicable {
        /// Position.
        slave: usize,
    },
    /// A rate outside 0..=1.
    #[error("frame loss rate {0} is not between 0 and 1")]
    Rate(f64),
    /// A probe wired to a device that is not what the wire needs.
    #[error("probe: device {device} {reason}")]
    Probe {
        /// Position of the device.
        device: usize,
        /// What it is not.
        reason: &'static str,
    },
}

/// What happened to one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// The frame came back, processed.
    Returned,
    /// The frame was lost (injected loss, or the link is down).
    Lost,
}

/// The devices in line, the link and the faults.
#[derive(Debug)]
pub struct Segment {
    slaves: Vec<Slave>,
    link_up: bool,
    loss_rate: f64,
    random: u64,
    spans: [DatagramSpan; MAX_DATAGRAMS],
    /// Per device: its process data are not served (`Fault::ProcessDataLoss`).
    no_process_data: Vec<bool>,
    /// Touch probes, and for each the system time from which the sensed drive's motion is
    /// still to be looked at.
    probes: Vec<(ProbeWire, u64)>,
    /// Frames offered to the segment.
    pub frames: u64,
    /// Frames lost by injection or a down link.
    pub lost: u64,
}

impl Segment {
    /// The devices in line, first to last; `seed` seeds the frame-loss generator.
    pub fn new(mut slaves: Vec<Slave>, seed: u64) -> Self {
        let count = slaves.len();
        for (n, slave) in slaves.iter_mut().enumerate() {
            slave.set_has_downstream(n + 1 < count);
        }
        Self {
            slaves,
            link_up: true,
            loss_rate: 0.0,
            no_process_data: vec![false; count],
            probes: Vec::new(),
            random: seed.max(1),
            spans: [DatagramSpan {
                header: 0,
                data_len: 0,
            }; MAX_DATAGRAMS],
            frames: 0,
            lost: 0,
        }
    }

    /// The devices.
    pub fn slaves(&self) -> &[Slave] {
        &self.slaves
    }

    /// One device.
    pub fn slave_mut(&mut self, position: usize) -> Option<&mut Slave> {
        self.slaves.get_mut(position)
    }

    /// Wires a touch probe in (refused when `sensed` or a `drives` entry is not a CSP drive,
    /// or `input` not an I/O terminal's input).
    pub fn wire_probe(&mut self, wire: ProbeWire) -> Result<(), SegmentError> {
        let is_drive = |slaves: &mut [Slave], n: usize| {
            slaves
                .get_mut(n)
                .is_some_and(|s| s.application_mut().as_any_mut().is::<CspDrive>())
        };
        if !wire.surface.is_finite() {
            return Err(SegmentError::Probe {
                device: wire.sensed,
                reason: "has a surface that is not a number",
            });
        }
        for n in std::iter::once(wire.sensed).chain(wire.drives.iter().copied()) {
            if !is_drive(&mut self.slaves, n) {
                return Err(SegmentError::Probe {
                    device: n,
                    reason: "is not a CSP drive",
                });
            }
        }
        if let Some(input) = wire.input {
            let terminal = self
                .slaves
                .get_mut(input.device)
                .is_some_and(|s| s.application_mut().as_any_mut().is::<DioTerminal>());
            if !terminal || input.bit >= 8 {
                return Err(SegmentError::Probe {
                    device: input.device,
                    reason: "is not an I/O terminal with that input (0 to 7)",
                });
            }
        }
        self.probes.push((wire, 0));
        self.run_probes();
        Ok(())
    }

    /// The probes' edges since they were last looked at, into the drives they are wired
    /// to, and their levels into the terminals' inputs.
    fn run_probes(&mut self) {
        for (wire, seen_ns) in &mut self.probes {
            let Some(sensed) = self
                .slaves
                .get_mut(wire.sensed)
                .and_then(|s| s.application_mut().as_any_mut().downcast_mut::<CspDrive>())
            else {
                continue;
            };
            let mut edges = [(0u64, false); 16];
            let mut count = 0;
            for m in sensed.motion_since(*seen_ns) {
                *seen_ns = m.end_ns;
                let (before, after) = (wire.contact(m.from), wire.contact(m.to));
                if before == after || m.from == m.to || count == edges.len() {
                    continue;
                }
                let share = ((wire.surface - m.from) / (m.to - m.from)).clamp(0.0, 1.0);
                let span = m.end_ns.saturating_sub(m.start_ns) as f64;
                edges[count] = (
                    m.start_ns.saturating_add((share * span).round() as u64),
                    after,
                );
                count += 1;
            }
            let level = wire.contact(sensed.true_position());
            for &n in &wire.drives {
                if let Some(drive) = self
                    .slaves
                    .get_mut(n)
                    .and_then(|s| s.application_mut().as_any_mut().downcast_mut::<CspDrive>())
                {
                    for &(at, rising) in &edges[..count] {
                        drive.touch_probe_input(at, rising);
                    }
                }
            }
            if let Some(input) = wire.input
                && let Some(terminal) = self.slaves.get_mut(input.device).and_then(|s| {
                    s.application_mut()
                        .as_any_mut()
                        .downcast_mut::<DioTerminal>()
                })
            {
                let mask = 1u8 << input.bit;
                let levels = terminal.inputs() & !mask;
                terminal.set_inputs(if level { levels | mask } else { levels });
            }
        }
    }

    /// Whether the link to the first device is up.
    pub fn link_up(&self) -> bool {
        self.link_up
    }

    /// Puts a fault in.
    pub fn inject(&mut self, fault: Fault) -> Result<(), SegmentError> {
        self.set_fault(fault, true)
    }

    /// Takes a fault out (a device that fell to SAFE-OP stays there until the master
    /// acknowledges; a drive still needs a fault reset).
    pub fn clear(&mut self, fault: Fault) -> Result<(), SegmentError> {
        self.set_fault(fault, false)
    }

    fn set_fault(&mut self, fault: Fault, active: bool) -> Result<(), SegmentError> {
        let count = self.slaves.len();
        match fault {
            Fault::FrameLoss { rate } => {
                if !(0.0..=1.0).contains(&rate) {
                    return Err(SegmentError::Rate(rate));
                }
                self.loss_rate = if active { rate } else { 0.0 };
            }
            Fault::FallToSafeOp { slave, code } => {
                let device = self
                    .slaves
                    .get_mut(slave)
                    .ok_or(SegmentError::NoSuchSlave { slave, count })?;
                if active {
                    device.fall_to(AlState::SafeOp, code);
                }
            }
            Fault::DriveFault { slave, error_code } => {
                let device = self
                    .slaves
                    .get_mut(slave)
                    .ok_or(SegmentError::NoSuchSlave { slave, count })?;
                if !device
                    .application_mut()
                    .inject_fault(active.then_some(error_code))
                {
                    return Err(SegmentError::NotApplicable { slave });
                }
            }
            Fault::LinkDown => self.link_up = !active,
            Fault::ProcessDataLoss { slave } => {
                let flag = self
                    .no_process_data
                    .get_mut(slave)
                    .ok_or(SegmentError::NoSuchSlave { slave, count })?;
                *flag = active;
            }
        }
        Ok(())
    }

    /// A uniform draw in [0, 1) from the seeded xorshift generator.
    fn draw(&mut self) -> f64 {
        let mut x = self.random;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.random = x;
        (x >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Sends `frame` (a whole Ethernet frame) through the segment, arriving at the first
    /// device at time `now_ns` of the segment's time base. On `Returned` the frame holds the
    /// reply, as the first device sends it back.
    pub fn process(&mut self, frame: &mut [u8], now_ns: u64) -> Result<Outcome, FrameError> {
        self.frames += 1;
        if !self.link_up || (self.loss_rate > 0.0 && self.draw() < self.loss_rate) {
            self.lost += 1;
            // The devices' clocks run on without the frame: SYNC0 events and watchdogs
            // happen on time, as on a real segment.
            for (position, slave) in self.slaves.iter_mut().enumerate() {
                slave.run_until(now_ns + position as u64 * HOP_DELAY_NS);
            }
            self.run_probes();
            return Ok(Outcome::Lost);
        }
        let count = datagrams(frame, &mut self.spans)?;
        let spans = self.spans;
        let devices = self.slaves.len() as u64;
        for (position, slave) in self.slaves.iter_mut().enumerate() {
            let t = now_ns + position as u64 * HOP_DELAY_NS;
            slave.advance_to(t);
            let serves_process_data = !self.no_process_data.get(position).copied().unwrap_or(false);
            for span in &spans[..count] {
                process_datagram(slave, frame, span, t, serves_process_data);
            }
        }
        // Back through the forwarding path: device n sees the frame again on port 1 after
        // it went to the last device and came back n hops.
        for (position, slave) in self.slaves.iter_mut().enumerate() {
            let back = 2 * (devices - 1) - position as u64;
            slave.finish_frame(now_ns + back * HOP_DELAY_NS);
        }
        // The first device marks the source address as locally administered on the way
        // back, so a master can tell its own frame from the reply.
        if let Some(byte) = frame.get_mut(6) {
            *byte |= 0x02;
        }
        self.run_probes();
        Ok(Outcome::Returned)
    }
}

fn process_datagram(
    slave: &mut Slave,
    frame: &mut [u8],
    span: &DatagramSpan,
    t: u64,
    serves_process_data: bool,
) {
    let header = span.header;
    let Some(command) = frame.get(header).copied().and_then(Command::from_code) else {
        return;
    };
    if !serves_process_data && matches!(command, Command::Lrd | Command::Lwr | Command::Lrw) {
        return;
    }
    let Some(address) = read_u32(frame, header + 2) else {
        return;
    };
    let position = (address & 0xFFFF) as u16;
    let addressing = match command {
        Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => {
            // Every device increments the position; the one that sees 0 is addressed.
            write_u16(frame, header + 2, position.wrapping_add(1));
            if position == 0 {
                Addressing::Addressed
            } else {
                Addressing::Other
            }
        }
        Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => {
            if position == slave.station_address() {
                Addressing::Addressed
            } else {
                Addressing::Other
            }
        }
        _ => Addressing::Other,
    };
    let data_range = span.data()..span.data() + span.data_len;
    let Some(data) = frame.get_mut(data_range) else {
        return;
    };
    let increment = slave.datagram(command, addressing, address, data, t);
    if increment > 0 {
        let wkc = read_u16(frame, span.wkc()).unwrap_or(0);
        write_u16(frame, span.wkc(), wkc.wrapping_add(increment));
    }
    debug_assert!(span.wkc() + WKC_LEN <= frame.len());
}
