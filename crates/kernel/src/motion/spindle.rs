//! The spindle as the program commands it: the programmed speed, constant surface speed
//! (G96: the speed follows the X set-point every servo period, as LinuxCNC's motion
//! controller does it), and the override on top.

use super::MotionCore;
use crate::config::MachineConfig;
use crate::messages::Aux;

/// G96: the spindle speed follows X.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ConstantSurfaceSpeed {
    /// Surface speed (mm/min) over 2π.
    pub(super) factor: f64,
    /// Machine X of the spindle axis.
    pub(super) x_centre: f64,
    /// D word, at most the spindle's top speed.
    pub(super) max_rpm: f64,
}

/// The spindle's command.
#[derive(Debug, Clone, Copy)]
pub(super) struct Spindle {
    /// The programmed speed (rpm, before the override).
    pub(super) programmed_rpm: f64,
    /// The spindle is commanded on.
    pub(super) on: bool,
    /// G96 in force.
    pub(super) css: Option<ConstantSurfaceSpeed>,
    /// The spindle's top speed (rpm).
    pub(super) max_rpm: f64,
}

impl Spindle {
    pub(super) fn new(config: &MachineConfig) -> Spindle {
        Spindle {
            programmed_rpm: 0.0,
            on: false,
            css: None,
            // A file without `[spindle]` gets the fieldbus's default spindle, as the
            // simulated machine does.
            max_rpm: config.spindle.map_or_else(
                || rtcnc_fieldbus::sim::SpindleConfig::default().max_speed_rpm,
                |s| s.max_speed_rpm,
            ),
        }
    }
}

impl MotionCore {
    /// The spindle speed to command (rpm, unsigned): the programmed speed times the
    /// override; under G96 the surface speed over 2π·|X − centre| at the X set-point, times
    /// the override, capped at D (as LinuxCNC's motion controller does it every period).
    pub(super) fn spindle_command(&self) -> f64 {
        // A rigid tap commands the spindle itself; the override does not apply.
        if let Some((_, rpm)) = self.tap_spindle() {
            return rpm;
        }
        self.spindle_command_with(self.overrides.spindle_factor())
    }

    /// The spindle speed the program commands, without the override.
    pub(super) fn spindle_command_without_override(&self) -> f64 {
        self.spindle_command_with(1.0)
    }

    fn spindle_command_with(&self, factor: f64) -> f64 {
        match self.spindle.css {
            Some(c) => {
                let radius = (self.out.now().target.setpoints.axes[0] - c.x_centre).abs();
                let rpm = if radius > 0.0 {
                    c.factor / radius
                } else {
                    c.max_rpm
                };
                (rpm * factor).min(c.max_rpm)
            }
            None => self.spindle.programmed_rpm * factor,
        }
    }

    /// G96, every servo period: the spindle speed follows the X set-point.
    pub(super) fn follow_surface_speed(&mut self) {
        if self.spindle.css.is_some() && self.spindle.on {
            let rpm = self.spindle_command();
            if self.interface.requests.spindle_rpm != rpm {
                self.requests_mut().spindle_rpm = rpm;
            }
        }
    }

    /// M3/M4/M5, S, G96/G97: the spindle's command to the machine logic.
    pub(super) fn command_spindle(&mut self, aux: Aux) {
        match aux {
            Aux::SpindleOn { rpm } => {
                self.spindle.on = rpm != 0.0;
                self.spindle.programmed_rpm = rpm.abs();
                let command = self.spindle_command();
                let mi = self.requests_mut();
                mi.spindle_orient = false;
                mi.spindle_on = rpm != 0.0;
                mi.spindle_reverse = rpm < 0.0;
                mi.spindle_rpm = command;
            }
            Aux::SpindleOff => {
                self.spindle.on = false;
                let mi = self.requests_mut();
                mi.spindle_orient = false;
                mi.spindle_on = false;
            }
            Aux::SpindleSpeed { rpm } => {
                self.spindle.programmed_rpm = rpm.abs();
                let command = self.spindle_command();
                self.requests_mut().spindle_rpm = command;
            }
            Aux::ConstantSurfaceSpeed {
                factor,
                x_centre,
                max_rpm,
            } => {
                self.spindle.css = Some(ConstantSurfaceSpeed {
                    factor,
                    x_centre,
                    max_rpm: max_rpm.min(self.spindle.max_rpm),
                });
                let command = self.spindle_command();
                self.requests_mut().spindle_rpm = command;
            }
            Aux::SurfaceSpeedOff => {
                self.spindle.css = None;
                let command = self.spindle_command();
                self.requests_mut().spindle_rpm = command;
            }
            // Tool compensation turns G96 into `ConstantSurfaceSpeed`; the rest are not
            // spindle functions.
            _ => {}
        }
    }
}
