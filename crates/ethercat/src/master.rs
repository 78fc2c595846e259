//! The master: bus start-up (scan, identity check, PDO mapping and SDO writes in PRE-OP,
//! distributed clocks, INIT → PRE-OP → SAFE-OP → OP) and the cyclic exchange behind the
//! [`Fieldbus`] trait.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ethercrab::subdevice_group::{DcConfiguration, HasDc, NoDc, Op, PreOp};
use ethercrab::{
    DcSync, DefaultLock, MainDevice, MainDeviceConfig, PduStorage, RetryBehaviour, SubDeviceGroup,
    SubDeviceState, Timeouts,
};
use rtcnc_fieldbus::{
    DriveMode, Fieldbus, FieldbusError, ProcessInputs, ProcessLayout, ProcessOutputs,
    check_exchange,
};
use rtcnc_rt::PiMutex;

use crate::al_status;
use crate::clock::Clock;
use crate::config::{ConfigError, EthercatConfig, ExpectedIdentity, SlaveConfig};
use crate::driver::{Driver, FRAMES, Stalled, TxRxCounters};
use crate::link::{Link, NetworkLink};
use crate::pdo::{DriveCodec, mapping_value};

/// Largest number of devices in the group (a power of two, as ethercrab requires).
const MAX_SLAVES: usize = 64;
/// Largest process data image (bytes): it travels in one frame.
pub const MAX_PDI: usize = 1024;
/// Bytes of PDU data per frame in ethercrab's storage.
const FRAME_DATA: usize = PduStorage::element_size(1100);
/// Wait for each reply at start-up.
const STARTUP_REPLY_TIMEOUT: Duration = Duration::from_millis(100);
/// Delay from the DC configuration to the first SYNC0 pulse.
const SYNC0_START_DELAY: Duration = Duration::from_millis(20);
/// The owner has taken the cycle over when two of its exchanges come at most this many
/// periods apart.
const HAND_OVER_PERIODS: u64 = 10;
/// The keeper sends a cycle only when the owner's last exchange is at least this many
/// periods old.
const KEEPER_IDLE_PERIODS: u64 = 2;
/// Stack of the keeper thread (ethercrab's cyclic futures, as on the owner's thread).
const KEEPER_STACK: usize = 2 << 20;

type Storage = PduStorage<FRAMES, FRAME_DATA>;
type Group<S, D> = SubDeviceGroup<MAX_SLAVES, MAX_PDI, DefaultLock, S, D>;

/// The group in OP, with or without distributed clocks.
enum OpGroup {
    Dc(Group<Op, HasDc>),
    Free(Group<Op, NoDc>),
}

/// What the master does with one device's process data.
#[derive(Debug)]
enum Device {
    Drive {
        joint: usize,
        codec: DriveCodec,
    },
    Dio {
        inputs: usize,
        outputs: usize,
        input_bits: usize,
        output_bits: usize,
    },
}

/// Why the bus did not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StartError {
    /// The configuration was refused.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The cycle period is not usable.
    #[error("EtherCAT cycle period {0:?} must be between 50 µs and 100 ms")]
    Period(Duration),
    /// The network interface could not be opened.
    #[error("EtherCAT interface {interface}: {reason}")]
    Interface {
        /// The interface.
        interface: String,
        /// The system's reason.
        reason: String,
    },
    /// The process may not open a raw socket.
    #[error(
        "EtherCAT interface {interface}: a raw socket was refused ({reason}): the master needs CAP_NET_RAW; run as root, or give the program the capability (setcap cap_net_raw+ep)"
    )]
    NoRawSocketPermission {
        /// The interface.
        interface: String,
        /// The system's reason.
        reason: String,
    },
    /// An operation on the bus failed.
    #[error("EtherCAT {phase}: {reason}")]
    Bus {
        /// What was being done.
        phase: &'static str,
        /// ethercrab's reason.
        reason: String,
    },
    /// The bus has a different number of devices than the configuration.
    #[error("EtherCAT bus has {found} devices, the configuration lists {expected}")]
    DeviceCount {
        /// Listed.
        expected: usize,
        /// Found.
        found: usize,
    },
    /// A device is not the one the configuration expects at its position.
    #[error(
        "EtherCAT device {position} ({name}): found {found}, the configuration expects {expected}"
    )]
    Identity {
        /// Position on the bus.
        position: usize,
        /// Configured name.
        name: String,
        /// Configured identity.
        expected: ExpectedIdentity,
        /// What its EEPROM says.
        found: ExpectedIdentity,
    },
    /// An SDO write in PRE-OP failed.
    #[error("EtherCAT device {position} ({name}): SDO {index:#06x}:{sub_index} write: {reason}")]
    Sdo {
        /// Position.
        position: usize,
        /// Name.
        name: String,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub_index: u8,
        /// Why (the abort code's meaning).
        reason: String,
    },
    /// A device refused a state change.
    #[error(
        "EtherCAT device {position} ({name}) refused {target}: it is in {state}, AL status code {code:#06x}: {reason}"
    )]
    StateRefused {
        /// Position.
        position: usize,
        /// Name.
        name: String,
        /// The state asked for.
        target: &'static str,
        /// The state it is in.
        state: &'static str,
        /// AL status code.
        code: u16,
        /// Its meaning.
        reason: &'static str,
    },
    /// A device's process data do not have the size its mapping gives.
    #[error(
        "EtherCAT device {position} ({name}): {what} are {found} bytes, its mapping gives {expected}"
    )]
    ProcessData {
        /// Position.
        position: usize,
        /// Name.
        name: String,
        /// "inputs" or "outputs".
        what: &'static str,
        /// Bytes from the mapping.
        expected: usize,
        /// Bytes the bus has.
        found: usize,
    },
}

impl StartError {
    /// A stable code.
    pub fn code(&self) -> &'static str {
        match self {
            Self::Config(e) => e.code(),
            Self::Period(_) => "ethercat.period",
            Self::Interface { .. } => "ethercat.interface",
            Self::NoRawSocketPermission { .. } => "ethercat.permission",
            Self::Bus { .. } => "ethercat.bus",
            Self::DeviceCount { .. } => "ethercat.device_count",
            Self::Identity { .. } => "ethercat.identity",
            Self::Sdo { .. } => "ethercat.sdo",
            Self::StateRefused { .. } => "ethercat.state_refused",
            Self::ProcessData { .. } => "ethercat.process_data",
        }
    }
}

/// Counters of the cyclic exchange.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MasterStatistics {
    /// Exchanges done.
    pub cycles: u64,
    /// Cycles whose frame came back with a wrong working counter.
    pub working_counter_errors: u64,
    /// Cycles whose frame did not come back in time.
    pub lost_frames: u64,
    /// The TX/RX's counters.
    pub tx_rx: TxRxCounters,
    /// The distributed clock's system time at the last exchange (ns), 0 without DC.
    pub dc_system_time: u64,
}

/// The EtherCAT master behind the [`Fieldbus`] trait.
///
/// From the end of start-up (the devices in OP) until its owner cycles, the master keeps
/// the bus cycling by itself on a thread of its own (the keeper), holding the drives
/// disabled where they stand, as start-up does: the devices' sync manager watchdogs
/// (typically 100 ms) must not expire while the owner is still being assembled (the
/// kernel builds its tasks and starts its real-time threads between the start and its
/// first cycle). The owner has taken the cycle over when two of its exchanges come within
/// ten periods of each other; the keeper then ends, and from then on an
/// owner that stops cycling is left to the devices' watchdogs, as on any master. Until
/// then the owner's exchange and the keeper's are serialised by a priority-inheriting
/// mutex: an owner's exchange waits at most for one keeper cycle (bounded by the reply
/// time-out); after the hand-over the mutex is never contended.
pub struct EthercatMaster {
    cyclic: Arc<PiMutex<Cyclic>>,
    layout: ProcessLayout,
    expected_wkc: u16,
    phase_error_ns: Option<i64>,
    inputs_fresh: bool,
    keeper: Option<Keeper>,
}

/// The keeper thread (see [`EthercatMaster`]).
struct Keeper {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<()>,
}

impl Drop for EthercatMaster {
    fn drop(&mut self) {
        if let Some(keeper) = self.keeper.take() {
            keeper.stop.store(true, Ordering::Release);
            // It ends within a period and one cycle.
            let _ = keeper.thread.join();
        }
    }
}

/// What the cycle needs: the bus, the devices and the counters.
struct Cyclic {
    maindevice: MainDevice<'static>,
    group: OpGroup,
    driver: Driver,
    devices: Vec<Device>,
    names: Vec<&'static str>,
    interface: &'static str,
    expected_wkc: u16,
    working_counter_limit: u32,
    consecutive_bad: u32,
    reply_timeout: Duration,
    period_ns: u64,
    shift_ns: u64,
    phase_error_ns: Option<i64>,
    estop_input: Option<usize>,
    statistics: MasterStatistics,
    /// The clock's time of the owner's last exchange.
    owner_last_ns: Option<u64>,
    /// The owner cycles: the keeper has ended (or never ran).
    handed_over: bool,
    /// The clock.
    clock: Clock,
    /// The keeper's inputs (read for the drives' positions, which it holds).
    hold_inputs: ProcessInputs,
}

impl std::fmt::Debug for EthercatMaster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("EthercatMaster");
        if let Some(cyclic) = self.cyclic.try_lock() {
            d.field("interface", &cyclic.interface)
                .field("devices", &cyclic.devices)
                .field("statistics", &cyclic.statistics);
        }
        d.finish_non_exhaustive()
    }
}

fn bus_error(phase: &'static str) -> impl Fn(ethercrab::error::Error) -> StartError {
    move |e| StartError::Bus {
        phase,
        reason: e.to_string(),
    }
}

fn stalled(phase: &'static str) -> impl Fn(Stalled) -> StartError {
    move |_| StartError::Bus {
        phase,
        reason: "no progress before the time-out".into(),
    }
}

/// Stack of the start-up thread.
const START_UP_STACK: usize = 32 << 20;

/// The interpolation time period (0x60C2) for `period_ns`: a value and a power of ten of
/// seconds, the value fitting in a byte.
fn interpolation_period(period_ns: u64) -> Option<(u8, i8)> {
    for exponent in [-3i8, -4, -5, -6] {
        let unit = 10u64.pow((9 + i32::from(exponent)) as u32);
        if period_ns % unit == 0 && period_ns / unit <= 255 {
            return Some(((period_ns / unit) as u8, exponent));
        }
    }
    None
}

impl EthercatMaster {
    /// Starts the bus on the configured network interface, for a cycle of `period`.
    pub fn start(config: &EthercatConfig, period: Duration) -> Result<Self, StartError> {
        config.validate()?;
        let link = NetworkLink::open(&config.interface).map_err(|e| {
            let interface = config.interface.clone();
            let reason = e.to_string();
            if e.kind() == std::io::ErrorKind::PermissionDenied {
                StartError::NoRawSocketPermission { interface, reason }
            } else {
                StartError::Interface { interface, reason }
            }
        })?;
        Self::start_with_link(config, period, Box::new(link), Clock::Monotonic)
    }

    /// Starts the bus on `link` with `clock` as time base (a simulated segment and a
    /// virtual clock in tests). Start-up paces its cycles with the clock.
    ///
    /// Start-up runs on a thread of its own with a large stack: ethercrab's start-up
    /// futures are deep (several megabytes unoptimised), more than a program's secondary
    /// threads have. The master is then handed back to the caller's thread.
    pub fn start_with_link(
        config: &EthercatConfig,
        period: Duration,
        link: Box<dyn Link>,
        clock: Clock,
    ) -> Result<Self, StartError> {
        config.validate()?;
        let config = config.clone();
        std::thread::Builder::new()
            .name("ethercat start-up".into())
            .stack_size(START_UP_STACK)
            .spawn(move || Self::start_here(&config, period, link, clock))
            .map_err(|e| StartError::Bus {
                phase: "start-up thread",
                reason: e.to_string(),
            })?
            .join()
            .unwrap_or_else(|_| {
                Err(StartError::Bus {
                    phase: "start-up",
                    reason: "the start-up thread panicked".into(),
                })
            })
    }

    fn start_here(
        config: &EthercatConfig,
        period: Duration,
        link: Box<dyn Link>,
        clock: Clock,
    ) -> Result<Self, StartError> {
        if period < Duration::from_micros(50) || period > Duration::from_millis(100) {
            return Err(StartError::Period(period));
        }
        let period_ns = period.as_nanos() as u64;
        let shift_ns = (period_ns as f64 * config.send_phase) as u64;
        let reply_timeout = config
            .reply_timeout_us
            .map_or(period / 2, |us| Duration::from_micros(u64::from(us)));
        let interface: &'static str = Box::leak(link.name().to_owned().into_boxed_str());
        // ethercrab's frame storage must outlive the master and its group; a master lives
        // for the process, so it is leaked (one per master, about 18 KiB).
        let storage: &'static Storage = Box::leak(Box::new(Storage::new()));
        let (tx, rx, pdu_loop) = storage.try_split().map_err(|()| StartError::Bus {
            phase: "frame storage",
            reason: "already in use".into(),
        })?;
        let maindevice = MainDevice::new(
            pdu_loop,
            Timeouts {
                state_transition: Duration::from_millis(u64::from(config.state_timeout_ms)),
                // Longer than any cyclic wait: a cyclic frame is given up by the exchange,
                // never retried by ethercrab.
                pdu: STARTUP_REPLY_TIMEOUT,
                // A device's EEPROM answers within microseconds; the margin is for a host
                // that does not run the start-up for a while (a loaded machine, where
                // simulated devices share its processors).
                eeprom: Duration::from_secs(1),
                wait_loop_delay: Duration::ZERO,
                mailbox_echo: Duration::from_millis(500),
                mailbox_response: Duration::from_millis(2000),
            },
            MainDeviceConfig {
                dc_static_sync_iterations: config.dc_static_sync_iterations,
                retry_behaviour: RetryBehaviour::Count(2),
            },
        );
        let driver = Driver::new(tx, rx, link);
        let names: Vec<&'static str> = config
            .slaves
            .iter()
            .map(|s| &*Box::leak(s.name().to_owned().into_boxed_str()))
            .collect();
        let mut master = Starting {
            config,
            maindevice: &maindevice,
            driver: &driver,
            clock,
            period,
            period_ns,
            shift_ns,
        };
        let (group, devices) = master.start()?;
        let layout = process_layout(config);
        let expected_wkc = expected_working_counter(&group, &maindevice);
        // A virtual clock moves only with its owner's cycles: no time passes between them
        // that a keeper would have to fill.
        let keep = !clock.is_virtual();
        let cyclic = Arc::new(PiMutex::new(Cyclic {
            maindevice,
            group,
            driver,
            devices,
            names,
            interface,
            expected_wkc,
            working_counter_limit: config.working_counter_limit,
            consecutive_bad: 0,
            reply_timeout,
            period_ns,
            shift_ns,
            phase_error_ns: None,
            estop_input: config.estop_input,
            statistics: MasterStatistics::default(),
            owner_last_ns: None,
            handed_over: !keep,
            clock,
            hold_inputs: ProcessInputs::new(&layout),
        }));
        let keeper = if keep {
            let stop = Arc::new(AtomicBool::new(false));
            let thread = std::thread::Builder::new()
                .name("ethercat keeper".into())
                .stack_size(KEEPER_STACK)
                .spawn({
                    let cyclic = Arc::clone(&cyclic);
                    let stop = Arc::clone(&stop);
                    move || keep_cycling(&cyclic, &stop, clock, period_ns)
                })
                .map_err(|e| StartError::Bus {
                    phase: "keeper thread",
                    reason: e.to_string(),
                })?;
            Some(Keeper { stop, thread })
        } else {
            None
        };
        Ok(Self {
            cyclic,
            layout,
            expected_wkc,
            phase_error_ns: None,
            inputs_fresh: true,
            keeper,
        })
    }

    /// The exchange counters (the owner's exchanges; the keeper's frames count in
    /// `tx_rx` only).
    pub fn statistics(&self) -> MasterStatistics {
        let cyclic = self.cyclic.lock();
        MasterStatistics {
            tx_rx: cyclic.driver.counters(),
            ..cyclic.statistics
        }
    }

    /// Round trips of the frames so far: a histogram in 1 µs bins and the longest (ns).
    /// Not for the real-time path (it copies the histogram).
    pub fn round_trips(&self) -> Option<(Vec<u32>, u64)> {
        self.cyclic.lock().driver.round_trips()
    }

    /// The working counter a good cycle returns.
    pub fn expected_working_counter(&self) -> u16 {
        self.expected_wkc
    }
}

/// The keeper (see [`EthercatMaster`]): every period, a cycle holding the drives, unless
/// the owner's last exchange is recent; ends when the owner has taken over or the master
/// is dropped.
fn keep_cycling(cyclic: &PiMutex<Cyclic>, stop: &AtomicBool, clock: Clock, period_ns: u64) {
    let mut next = clock.now_ns();
    loop {
        next = next.saturating_add(period_ns).max(clock.now_ns());
        clock.sleep_until(next);
        if stop.load(Ordering::Acquire) {
            return;
        }
        let mut cyclic = cyclic.lock();
        if cyclic.handed_over {
            return;
        }
        let now = clock.now_ns();
        let owner_idle = cyclic.owner_last_ns.is_none_or(|last| {
            now.saturating_sub(last) >= KEEPER_IDLE_PERIODS.saturating_mul(period_ns)
        });
        if owner_idle {
            cyclic.hold_cycle();
        }
    }
}

impl Cyclic {
    /// One cycle of the keeper: the drives held disabled at their actual positions, the
    /// positions read back. Its errors are the owner's to see on its next exchange.
    fn hold_cycle(&mut self) {
        let maindevice = &self.maindevice;
        for (position, device) in self.devices.iter_mut().enumerate() {
            let Device::Drive { codec, .. } = device else {
                continue;
            };
            match &self.group {
                OpGroup::Dc(g) => {
                    if let Ok(s) = g.subdevice(maindevice, position) {
                        codec.encode_hold(&mut s.outputs_raw_mut());
                    }
                }
                OpGroup::Free(g) => {
                    if let Ok(s) = g.subdevice(maindevice, position) {
                        codec.encode_hold(&mut s.outputs_raw_mut());
                    }
                }
            }
        }
        let deadline = Instant::now() + self.reply_timeout;
        let good = match &self.group {
            OpGroup::Dc(g) => self
                .driver
                .cycle(g.tx_rx_dc(maindevice), deadline)
                .is_some_and(|r| r.is_ok_and(|r| r.working_counter == self.expected_wkc)),
            OpGroup::Free(g) => self
                .driver
                .cycle(g.tx_rx(maindevice), deadline)
                .is_some_and(|r| r.is_ok_and(|r| r.working_counter == self.expected_wkc)),
        };
        if !good {
            return;
        }
        // The positions, so that the next hold is where the drives stand.
        let period_s = self.period_ns as f64 * 1e-9;
        for (position, device) in self.devices.iter_mut().enumerate() {
            match &self.group {
                OpGroup::Dc(g) => {
                    if let Ok(s) = g.subdevice(maindevice, position) {
                        decode(device, &s.inputs_raw(), period_s, &mut self.hold_inputs);
                    }
                }
                OpGroup::Free(g) => {
                    if let Ok(s) = g.subdevice(maindevice, position) {
                        decode(device, &s.inputs_raw(), period_s, &mut self.hold_inputs);
                    }
                }
            }
        }
    }

    fn write_outputs(&mut self, outputs: &ProcessOutputs) {
        let maindevice = &self.maindevice;
        let write = |position: usize, device: &mut Device| {
            let subdevice = match &self.group {
                OpGroup::Dc(g) => g.subdevice(maindevice, position).ok().map(|s| {
                    let mut o = s.outputs_raw_mut();
                    encode(device, outputs, &mut o);
                }),
                OpGroup::Free(g) => g.subdevice(maindevice, position).ok().map(|s| {
                    let mut o = s.outputs_raw_mut();
                    encode(device, outputs, &mut o);
                }),
            };
            let _ = subdevice;
        };
        for (position, device) in self.devices.iter_mut().enumerate() {
            write(position, device);
        }
    }

    fn read_inputs(&mut self, period_s: f64, inputs: &mut ProcessInputs) {
        let maindevice = &self.maindevice;
        for (position, device) in self.devices.iter_mut().enumerate() {
            match &self.group {
                OpGroup::Dc(g) => {
                    if let Ok(s) = g.subdevice(maindevice, position) {
                        decode(device, &s.inputs_raw(), period_s, inputs);
                    }
                }
                OpGroup::Free(g) => {
                    if let Ok(s) = g.subdevice(maindevice, position) {
                        decode(device, &s.inputs_raw(), period_s, inputs);
                    }
                }
            }
        }
        if let Some(input) = self.estop_input {
            inputs.estop_active = !inputs.digital.get(input).copied().unwrap_or(false);
        }
    }

    /// The first device not in OP, as a fieldbus error (reads its AL status code: one more
    /// frame, on the way to a fault).
    fn device_state_error(&self, states: &[SubDeviceState], deadline: Instant) -> FieldbusError {
        let position = states
            .iter()
            .position(|s| *s != SubDeviceState::Op)
            .unwrap_or(0);
        let state = states
            .get(position)
            .copied()
            .unwrap_or(SubDeviceState::None);
        let code = match &self.group {
            OpGroup::Dc(g) => g.subdevice(&self.maindevice, position).ok().and_then(|s| {
                self.driver
                    .cycle(s.register_read::<u16>(0x0134u16), deadline)
                    .and_then(Result::ok)
            }),
            OpGroup::Free(g) => g.subdevice(&self.maindevice, position).ok().and_then(|s| {
                self.driver
                    .cycle(s.register_read::<u16>(0x0134u16), deadline)
                    .and_then(Result::ok)
            }),
        }
        .unwrap_or(0);
        FieldbusError::DeviceState {
            position: position as u16,
            name: self.names.get(position).copied().unwrap_or("?"),
            state: al_status::state_name(state_bits(state)),
            code,
            reason: al_status::describe(code),
        }
    }

    fn bad_cycle(&mut self, received: u16, lost: bool) -> Result<(), FieldbusError> {
        self.consecutive_bad += 1;
        if lost {
            self.statistics.lost_frames += 1;
        } else {
            self.statistics.working_counter_errors += 1;
        }
        if lost && !self.driver.link_up() {
            return Err(FieldbusError::LinkDown {
                interface: self.interface,
            });
        }
        if self.consecutive_bad >= self.working_counter_limit {
            return Err(if lost {
                FieldbusError::CommunicationLost
            } else {
                FieldbusError::WorkingCounter {
                    expected: self.expected_wkc,
                    received,
                    consecutive: self.consecutive_bad,
                }
            });
        }
        // Below the limit: the inputs stay those of the last good cycle.
        Ok(())
    }
}

fn state_bits(state: SubDeviceState) -> u8 {
    match state {
        SubDeviceState::None => 0,
        SubDeviceState::Init => 1,
        SubDeviceState::PreOp => 2,
        SubDeviceState::Bootstrap => 3,
        SubDeviceState::SafeOp => 4,
        SubDeviceState::Op => 8,
        SubDeviceState::Other(bits) => bits,
    }
}

fn encode(device: &mut Device, outputs: &ProcessOutputs, bytes: &mut [u8]) {
    match device {
        Device::Drive { joint, codec } => {
            if let Some(command) = outputs.joints.get(*joint) {
                codec.encode(command, bytes);
            }
        }
        Device::Dio {
            outputs: first,
            output_bits,
            ..
        } => {
            for bit in 0..*output_bits {
                let on = outputs.digital.get(*first + bit).copied().unwrap_or(false);
                if let Some(byte) = bytes.get_mut(bit / 8) {
                    let mask = 1 << (bit % 8);
                    *byte = if on { *byte | mask } else { *byte & !mask };
                }
            }
        }
    }
}

fn decode(device: &mut Device, bytes: &[u8], period_s: f64, inputs: &mut ProcessInputs) {
    match device {
        Device::Drive { joint, codec } => {
            if let Some(feedback) = inputs.joints.get_mut(*joint) {
                codec.decode(bytes, period_s, feedback);
            }
        }
        Device::Dio {
            inputs: first,
            input_bits,
            ..
        } => {
            for bit in 0..*input_bits {
                let on = bytes
                    .get(bit / 8)
                    .is_some_and(|b| b & (1 << (bit % 8)) != 0);
                if let Some(input) = inputs.digital.get_mut(*first + bit) {
                    *input = on;
                }
            }
        }
    }
}

fn process_layout(config: &EthercatConfig) -> ProcessLayout {
    let mut layout = ProcessLayout::default();
    for slave in &config.slaves {
        match slave {
            SlaveConfig::Cia402 { .. } => layout.joints.push(DriveMode::Csp),
            SlaveConfig::Dio {
                inputs,
                outputs,
                input_bits,
                output_bits,
                ..
            } => {
                layout.digital_inputs = layout.digital_inputs.max(inputs + input_bits);
                layout.digital_outputs = layout.digital_outputs.max(outputs + output_bits);
            }
        }
    }
    layout
}

fn expected_working_counter(group: &OpGroup, maindevice: &MainDevice<'_>) -> u16 {
    let mut wkc = 0u16;
    let mut count = |inputs: usize, outputs: usize| {
        wkc += u16::from(inputs > 0) + 2 * u16::from(outputs > 0);
    };
    match group {
        OpGroup::Dc(g) => g
            .iter(maindevice)
            .for_each(|s| count(s.inputs_raw().len(), s.outputs_raw().len())),
        OpGroup::Free(g) => g
            .iter(maindevice)
            .for_each(|s| count(s.inputs_raw().len(), s.outputs_raw().len())),
    }
    wkc
}

/// The start-up sequence.
struct Starting<'a> {
    config: &'a EthercatConfig,
    maindevice: &'a MainDevice<'static>,
    driver: &'a Driver,
    clock: Clock,
    period: Duration,
    period_ns: u64,
    shift_ns: u64,
}

impl Starting<'_> {
    fn block_on<F: std::future::Future>(
        &self,
        future: F,
        phase: &'static str,
    ) -> Result<F::Output, StartError> {
        let timeout = Duration::from_millis(u64::from(self.config.state_timeout_ms))
            + Duration::from_secs(10);
        self.driver
            .block_on(future, STARTUP_REPLY_TIMEOUT, timeout)
            .map_err(stalled(phase))
    }

    fn start(&mut self) -> Result<(OpGroup, Vec<Device>), StartError> {
        let maindevice = self.maindevice;
        let clock = self.clock;
        let group: Group<PreOp, NoDc> = self
            .block_on(
                maindevice.init_single_group::<MAX_SLAVES, MAX_PDI>(move || clock.now_ns()),
                "bus scan",
            )?
            .map_err(|e| self.refusal_or(e, "PRE-OP", "bus scan"))?;
        if group.len() != self.config.slaves.len() {
            return Err(StartError::DeviceCount {
                expected: self.config.slaves.len(),
                found: group.len(),
            });
        }
        for (position, (subdevice, slave)) in
            group.iter(maindevice).zip(&self.config.slaves).enumerate()
        {
            let id = subdevice.identity();
            let found = ExpectedIdentity {
                vendor_id: id.vendor_id,
                product_code: id.product_id,
                revision: id.revision,
            };
            if found != slave.identity() {
                return Err(StartError::Identity {
                    position,
                    name: slave.name().to_owned(),
                    expected: slave.identity(),
                    found,
                });
            }
        }
        let mut devices = Vec::new();
        for (position, slave) in self.config.slaves.iter().enumerate() {
            devices.push(self.configure(&group, position, slave)?);
        }
        if let Some(ms) = self.config.sm_watchdog_ms {
            // 100 µs watchdog ticks: divider 2498 of the 25 MHz clock ((2498 + 2) × 40 ns).
            for subdevice in group.iter(maindevice) {
                let write = async {
                    subdevice.register_write(0x0400u16, 2498u16).await?;
                    subdevice
                        .register_write(0x0420u16, ms.saturating_mul(10))
                        .await
                };
                self.block_on(write, "sync manager watchdog")?
                    .map_err(bus_error("sync manager watchdog"))?;
            }
        }
        let mut group = group;
        let mut any_dc = false;
        if self.config.distributed_clocks {
            for mut subdevice in group.iter_mut(maindevice) {
                if subdevice.dc_support().any() {
                    subdevice.set_dc_sync(DcSync::Sync0);
                    any_dc = true;
                }
            }
        }
        let group = self
            .block_on(group.into_pre_op_pdi(maindevice), "PRE-OP process data")?
            .map_err(|e| self.refusal_or(e, "PRE-OP", "process data mapping"))?;
        for (position, (subdevice, device)) in group.iter(maindevice).zip(&devices).enumerate() {
            if let Device::Drive { codec, .. } = device {
                let (out_len, in_len) = codec.lengths();
                for (what, expected, found) in [
                    ("outputs", out_len, subdevice.outputs_raw().len()),
                    ("inputs", in_len, subdevice.inputs_raw().len()),
                ] {
                    if expected != found {
                        return Err(StartError::ProcessData {
                            position,
                            name: self.config.slaves[position].name().to_owned(),
                            what,
                            expected,
                            found,
                        });
                    }
                }
            }
        }
        // Inputs mean something once SYNC0 has run: start-up cycles until then.
        let sync_start_ns = self.clock.now_ns() + SYNC0_START_DELAY.as_nanos() as u64;
        let op = if any_dc {
            let group = self
                .block_on(
                    group.configure_dc_sync(
                        maindevice,
                        DcConfiguration {
                            start_delay: SYNC0_START_DELAY,
                            sync0_period: self.period,
                            sync0_shift: Duration::from_nanos(self.shift_ns),
                        },
                    ),
                    "distributed clocks",
                )?
                .map_err(bus_error("distributed clocks"))?;
            let group = self
                .block_on(group.into_safe_op(maindevice), "SAFE-OP")?
                .map_err(|e| self.refusal_or(e, "SAFE-OP", "SAFE-OP"))?;
            let group = self
                .block_on(group.request_into_op(maindevice), "OP")?
                .map_err(|e| self.refusal_or(e, "OP", "OP"))?;
            OpGroup::Dc(group)
        } else {
            let group = self
                .block_on(group.into_safe_op(maindevice), "SAFE-OP")?
                .map_err(|e| self.refusal_or(e, "SAFE-OP", "SAFE-OP"))?;
            let group = self
                .block_on(group.request_into_op(maindevice), "OP")?
                .map_err(|e| self.refusal_or(e, "OP", "OP"))?;
            OpGroup::Free(group)
        };
        let ready_ns = if any_dc {
            sync_start_ns + 2 * self.period_ns
        } else {
            0
        };
        self.cycle_until_op(&op, &mut devices, ready_ns)?;
        Ok((op, devices))
    }

    /// Sends process data every period (holding the drives disabled where they stand)
    /// until every device is in OP and the clock has passed `ready_ns`.
    fn cycle_until_op(
        &self,
        group: &OpGroup,
        devices: &mut [Device],
        ready_ns: u64,
    ) -> Result<(), StartError> {
        let maindevice = self.maindevice;
        let end = Instant::now() + Duration::from_millis(u64::from(self.config.state_timeout_ms));
        let mut next = self.clock.now_ns();
        let mut scratch = ProcessInputs {
            joints: vec![Default::default(); MAX_SLAVES],
            ..ProcessInputs::default()
        };
        loop {
            for (position, device) in devices.iter_mut().enumerate() {
                let mut hold = |bytes: &mut [u8]| {
                    if let Device::Drive { codec, .. } = device {
                        codec.encode_hold(bytes);
                    }
                };
                match group {
                    OpGroup::Dc(g) => {
                        if let Ok(s) = g.subdevice(maindevice, position) {
                            hold(&mut s.outputs_raw_mut());
                        }
                    }
                    OpGroup::Free(g) => {
                        if let Ok(s) = g.subdevice(maindevice, position) {
                            hold(&mut s.outputs_raw_mut());
                        }
                    }
                }
            }
            let states = match group {
                OpGroup::Dc(g) => self
                    .block_on(g.tx_rx_dc(maindevice), "OP")?
                    .map(|r| (r.all_op(), r.subdevice_states)),
                OpGroup::Free(g) => self
                    .block_on(g.tx_rx(maindevice), "OP")?
                    .map(|r| (r.all_op(), r.subdevice_states)),
            }
            .map_err(bus_error("OP"))?;
            // Read the positions, so that holding sends the actual position.
            for (position, device) in devices.iter_mut().enumerate() {
                let mut read = |bytes: &[u8]| decode(device, bytes, 1e-3, &mut scratch);
                match group {
                    OpGroup::Dc(g) => {
                        if let Ok(s) = g.subdevice(maindevice, position) {
                            read(&s.inputs_raw());
                        }
                    }
                    OpGroup::Free(g) => {
                        if let Ok(s) = g.subdevice(maindevice, position) {
                            read(&s.inputs_raw());
                        }
                    }
                }
            }
            if states.0 && self.clock.now_ns() >= ready_ns {
                return Ok(());
            }
            if Instant::now() >= end {
                let position = states
                    .1
                    .iter()
                    .position(|s| *s != SubDeviceState::Op)
                    .unwrap_or(0);
                return Err(self.refusal(position, "OP").unwrap_or(StartError::Bus {
                    phase: "OP",
                    reason: "devices did not reach OP in time".into(),
                }));
            }
            next += self.period_ns;
            self.clock.sleep_until(next);
        }
    }

    /// PRE-OP settings of one device: PDO mapping and assignment, mode CSP, the
    /// interpolation period, synchronisation, limits, the configured SDOs.
    fn configure(
        &self,
        group: &Group<PreOp, NoDc>,
        position: usize,
        slave: &SlaveConfig,
    ) -> Result<Device, StartError> {
        let maindevice = self.maindevice;
        match slave {
            SlaveConfig::Dio {
                inputs,
                outputs,
                input_bits,
                output_bits,
                ..
            } => Ok(Device::Dio {
                inputs: *inputs,
                outputs: *outputs,
                input_bits: *input_bits,
                output_bits: *output_bits,
            }),
            SlaveConfig::Cia402 {
                name,
                joint,
                counts_per_unit,
                rated_torque_nm,
                rx_pdo,
                tx_pdo,
                following_error_window,
                position_limits,
                max_motor_speed_rpm,
                max_torque_permille,
                sdo,
                ..
            } => {
                let subdevice = group
                    .subdevice(maindevice, position)
                    .map_err(bus_error("device lookup"))?;
                let write = |index: u16, sub_index: u8, value: i64, bytes: u8| {
                    let future = async {
                        match bytes {
                            1 => subdevice.sdo_write(index, sub_index, value as u8).await,
                            2 => subdevice.sdo_write(index, sub_index, value as u16).await,
                            _ => subdevice.sdo_write(index, sub_index, value as u32).await,
                        }
                    };
                    self.block_on(future, "SDO write")?
                        .map_err(|e| StartError::Sdo {
                            position,
                            name: name.clone(),
                            index,
                            sub_index,
                            reason: e.to_string(),
                        })
                };
                write(0x1C12, 0, 0, 1)?;
                write(0x1600, 0, 0, 1)?;
                for (n, object) in rx_pdo.iter().enumerate() {
                    let value = mapping_value(object.index(), object.bits());
                    write(0x1600, n as u8 + 1, i64::from(value), 4)?;
                }
                write(0x1600, 0, rx_pdo.len() as i64, 1)?;
                write(0x1C12, 1, 0x1600, 2)?;
                write(0x1C12, 0, 1, 1)?;
                write(0x1C13, 0, 0, 1)?;
                write(0x1A00, 0, 0, 1)?;
                for (n, object) in tx_pdo.iter().enumerate() {
                    let value = mapping_value(object.index(), object.bits());
                    write(0x1A00, n as u8 + 1, i64::from(value), 4)?;
                }
                write(0x1A00, 0, tx_pdo.len() as i64, 1)?;
                write(0x1C13, 1, 0x1A00, 2)?;
                write(0x1C13, 0, 1, 1)?;
                write(0x6060, 0, i64::from(crate::MODE_CSP), 1)?;
                if let Some((value, exponent)) = interpolation_period(self.period_ns) {
                    write(0x60C2, 1, i64::from(value), 1)?;
                    write(0x60C2, 2, i64::from(exponent), 1)?;
                }
                if self.config.distributed_clocks {
                    // Both sync managers synchronous to SYNC0, at the cycle period.
                    for index in [0x1C32, 0x1C33] {
                        write(index, 1, 2, 2)?;
                        write(index, 2, self.period_ns as i64, 4)?;
                    }
                }
                let counts = |units: f64| (units * counts_per_unit).round() as i64;
                if let Some(window) = following_error_window {
                    write(0x6065, 0, counts(*window).clamp(0, i64::from(u32::MAX)), 4)?;
                }
                if let Some([min, max]) = position_limits {
                    let clamp = |c: i64| c.clamp(i64::from(i32::MIN), i64::from(i32::MAX));
                    write(0x607D, 1, clamp(counts(*min)), 4)?;
                    write(0x607D, 2, clamp(counts(*max)), 4)?;
                }
                if let Some(rpm) = max_motor_speed_rpm {
                    write(0x6080, 0, i64::from(*rpm), 4)?;
                }
                if let Some(permille) = max_torque_permille {
                    write(0x6072, 0, i64::from(*permille), 2)?;
                }
                for extra in sdo {
                    write(extra.index, extra.sub_index, extra.value, extra.bytes)?;
                }
                Ok(Device::Drive {
                    joint: *joint,
                    codec: DriveCodec::new(rx_pdo, tx_pdo, *counts_per_unit, *rated_torque_nm),
                })
            }
        }
    }

    /// The device that refused `target`, with its AL status code.
    fn refusal(&self, position: usize, target: &'static str) -> Option<StartError> {
        let maindevice = self.maindevice;
        let address = 0x1000u16.checked_add(u16::try_from(position).ok()?)?;
        let status = self
            .driver
            .block_on(
                async {
                    let state = ethercrab::Command::fprd(address, 0x0130)
                        .receive::<u16>(maindevice)
                        .await?;
                    let code = ethercrab::Command::fprd(address, 0x0134)
                        .receive::<u16>(maindevice)
                        .await?;
                    Ok::<_, ethercrab::error::Error>((state, code))
                },
                STARTUP_REPLY_TIMEOUT,
                Duration::from_secs(1),
            )
            .ok()?
            .ok()?;
        Some(StartError::StateRefused {
            position,
            name: self.config.slaves.get(position)?.name().to_owned(),
            target,
            state: al_status::state_name(status.0 as u8),
            code: status.1,
            reason: al_status::describe(status.1),
        })
    }

    /// A failed state change: the first device that shows an error flag, else the error.
    fn refusal_or(
        &self,
        error: ethercrab::error::Error,
        target: &'static str,
        phase: &'static str,
    ) -> StartError {
        for position in 0..self.config.slaves.len() {
            if let Some(refusal @ StartError::StateRefused { code, .. }) =
                self.refusal(position, target)
                && code != 0
            {
                return refusal;
            }
        }
        bus_error(phase)(error)
    }
}

impl Fieldbus for EthercatMaster {
    fn layout(&self) -> &ProcessLayout {
        &self.layout
    }

    fn exchange(
        &mut self,
        period_s: f64,
        outputs: &ProcessOutputs,
        inputs: &mut ProcessInputs,
    ) -> Result<(), FieldbusError> {
        check_exchange(&self.layout, period_s, outputs, inputs)?;
        // Uncontended once the owner has taken over; before, it waits at most for the
        // keeper's cycle in progress.
        let mut cyclic = self.cyclic.lock();
        let result = cyclic.exchange(period_s, outputs, inputs);
        self.phase_error_ns = cyclic.phase_error_ns;
        self.inputs_fresh = cyclic.consecutive_bad == 0;
        result
    }

    fn cycle_phase_error_ns(&self) -> Option<i64> {
        self.phase_error_ns
    }

    fn inputs_fresh(&self) -> bool {
        self.inputs_fresh
    }
}

impl Cyclic {
    fn exchange(
        &mut self,
        period_s: f64,
        outputs: &ProcessOutputs,
        inputs: &mut ProcessInputs,
    ) -> Result<(), FieldbusError> {
        if !self.handed_over {
            let now = self.clock.now_ns();
            self.handed_over = self.owner_last_ns.is_some_and(|last| {
                now.saturating_sub(last) <= HAND_OVER_PERIODS.saturating_mul(self.period_ns)
            });
            self.owner_last_ns = Some(now);
        }
        self.statistics.cycles += 1;
        // Measured afresh by each exchange that brings the reference clock's time back:
        // a lost frame measures nothing, and a caller must not correct twice for the last.
        self.phase_error_ns = None;
        self.write_outputs(outputs);
        let deadline = Instant::now() + self.reply_timeout;
        let maindevice = &self.maindevice;
        let response = match &self.group {
            OpGroup::Dc(g) => self
                .driver
                .cycle(g.tx_rx_dc(maindevice), deadline)
                .map(|r| {
                    r.map(|r| {
                        let all_op = r.all_op();
                        (
                            r.working_counter,
                            all_op,
                            Some(r.extra.dc_system_time),
                            r.subdevice_states,
                        )
                    })
                }),
            OpGroup::Free(g) => self
                .driver
                .cycle(g.tx_rx(maindevice), deadline)
                .map(|r| r.map(|r| (r.working_counter, r.all_op(), None, r.subdevice_states))),
        };
        let (wkc, all_op, dc_time, states) = match response {
            Some(Ok(response)) => response,
            Some(Err(_)) | None => return self.bad_cycle(0, true),
        };
        if let Some(time) = dc_time {
            self.statistics.dc_system_time = time;
            let offset = (time % self.period_ns) as i64 - self.shift_ns as i64;
            let half = (self.period_ns / 2) as i64;
            let period = self.period_ns as i64;
            // Into (-period/2, period/2]: early or late by less than half a cycle.
            let wrapped = (offset + half).rem_euclid(period) - half;
            self.phase_error_ns = Some(wrapped);
        }
        if !all_op {
            self.consecutive_bad += 1;
            return Err(self.device_state_error(&states, Instant::now() + self.reply_timeout));
        }
        if wkc != self.expected_wkc {
            return self.bad_cycle(wkc, false);
        }
        self.consecutive_bad = 0;
        self.read_inputs(period_s, inputs);
        Ok(())
    }
}
