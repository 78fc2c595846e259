//! A simulated bus for the master's tests: a segment of simulated devices in the same
//! process, on a virtual clock, and the master configuration that matches it.
#![allow(dead_code)]

use std::sync::Arc;
use std::time::Duration;

use rtcnc_ecat_slave_sim::dio::{DIO_PRODUCT_CODE, DioTerminal};
use rtcnc_ecat_slave_sim::drive::{CspDrive, DRIVE_PRODUCT_CODE, SIMULATOR_VENDOR_ID};
use rtcnc_ecat_slave_sim::{Segment, SegmentConfig};
use rtcnc_ethercat::{Clock, EthercatConfig, EthercatMaster, SimulatedLink, StartError};
use rtcnc_fieldbus::{Fieldbus, ProcessInputs, ProcessOutputs};
use rtcnc_rt::PiMutex;

/// Encoder increments per mm of the simulated drives (17 bits on a 5 mm lead).
pub const COUNTS_PER_MM: f64 = 131072.0 / 5.0;

/// The segment: `drives` CSP drives, then (if `dio`) one DIO terminal.
pub fn segment_toml(drives: usize, dio: bool, drift_ppm: f64) -> String {
    let mut text =
        format!("[[slaves]]\nkind = \"csp_drive\"\ncount = {drives}\ndrift_ppm = {drift_ppm:?}\n");
    if dio {
        text.push_str("[[slaves]]\nkind = \"dio\"\n");
    }
    text
}

/// The master's configuration for that segment.
pub fn master_toml(drives: usize, dio: bool) -> String {
    let mut text = String::from("interface = \"sim0\"\nworking_counter_limit = 3\n");
    for joint in 0..drives {
        text.push_str(&format!(
            "[[slaves]]\nkind = \"cia402\"\nname = \"J{joint}\"\nvendor_id = {SIMULATOR_VENDOR_ID}\nproduct_code = {DRIVE_PRODUCT_CODE}\nrevision = 0x00010000\njoint = {joint}\ncounts_per_unit = {COUNTS_PER_MM:?}\nrated_torque_nm = 1.27\n"
        ));
    }
    if dio {
        text.push_str(&format!(
            "[[slaves]]\nkind = \"dio\"\nname = \"IO\"\nvendor_id = {SIMULATOR_VENDOR_ID}\nproduct_code = {DIO_PRODUCT_CODE}\nrevision = 0x00010000\ninputs = 0\noutputs = 0\n"
        ));
    }
    text
}

/// A running simulated bus.
pub struct Bus {
    pub master: EthercatMaster,
    pub segment: Arc<PiMutex<Segment>>,
    pub clock: Clock,
    pub period: Duration,
    pub outputs: ProcessOutputs,
    pub inputs: ProcessInputs,
}

pub fn start(segment: &str, master: &str, period: Duration) -> Result<Bus, StartError> {
    let segment: SegmentConfig = toml::from_str(segment).expect("segment TOML");
    let segment = Arc::new(PiMutex::new(segment.build().expect("segment")));
    let config: EthercatConfig = toml::from_str(master).expect("master TOML");
    let clock = Clock::new_virtual(1_000_000_000);
    let link = SimulatedLink::new(Arc::clone(&segment), clock);
    let master = EthercatMaster::start_with_link(&config, period, Box::new(link), clock)?;
    let outputs = ProcessOutputs::new(master.layout());
    let inputs = ProcessInputs::new(master.layout());
    Ok(Bus {
        master,
        segment,
        clock,
        period,
        outputs,
        inputs,
    })
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("master", &self.master)
            .finish_non_exhaustive()
    }
}

impl Bus {
    /// One cycle: the clock moves one period, then the exchange.
    pub fn cycle(&mut self) -> Result<(), rtcnc_fieldbus::FieldbusError> {
        self.clock.advance(self.period.as_nanos() as u64);
        self.master
            .exchange(self.period.as_secs_f64(), &self.outputs, &mut self.inputs)
    }

    /// The true load position of the drive at `position` (mm).
    pub fn true_position(&self, position: usize) -> f64 {
        let mut segment = self.segment.lock();
        let slave = segment.slave_mut(position).expect("device");
        slave
            .application_mut()
            .as_any_mut()
            .downcast_mut::<CspDrive>()
            .expect("a drive")
            .true_position()
    }

    /// Sets the input levels of the DIO terminal at `position`.
    pub fn set_dio_inputs(&self, position: usize, levels: u8) {
        let mut segment = self.segment.lock();
        let slave = segment.slave_mut(position).expect("device");
        slave
            .application_mut()
            .as_any_mut()
            .downcast_mut::<DioTerminal>()
            .expect("a terminal")
            .set_inputs(levels);
    }

    /// The output levels of the DIO terminal at `position`.
    pub fn dio_outputs(&self, position: usize) -> u8 {
        let mut segment = self.segment.lock();
        let slave = segment.slave_mut(position).expect("device");
        slave
            .application_mut()
            .as_any_mut()
            .downcast_mut::<DioTerminal>()
            .expect("a terminal")
            .outputs()
    }
}
