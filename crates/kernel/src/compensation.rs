//! The tool-compensation task: applies the tool length offset, the work offsets (G54..,
//! G92, XY rotation) and the length units to the interpreter's blocks, and turns them into
//! the planner's moves in machine millimetres and seconds. (Cutter radius compensation
//! runs inside the interpreter task, on the canonical stream it works on.) Event task,
//! woken by blocks from the interpreter; allocation-free.

use rtcnc_motion::{AXES, Bezier, Feed, Move, MoveKind, PathMode, TipPath};
use rtcnc_rt::{Context, Next};

use crate::messages::{Aux, MachineBlock, ProgramBlock};
use crate::shared::{Shared, Tagged};

pub(crate) struct CompensationStage {
    shared: Shared,
    mm_per_unit: f64,
    work: [f64; AXES],
    g92: [f64; AXES],
    rotation_deg: f64,
    tool: [f64; AXES],
    /// Feed rate in mm (per minute, or per revolution), converted with the units in force
    /// when it was set, as LinuxCNC's canonical layer does: `G20 F6` sets the feed before
    /// the units (RS274/NGC's order of execution), so F6 is in the units before G20.
    feed_mm: f64,
    per_revolution: bool,
    spindle_rpm: f64,
    mode: PathMode,
    /// The blend tolerance of plain G64 (mm), from the machine file.
    default_blend_tolerance: f64,
    /// G33/G76: the pitch (mm per revolution) of the synchronised feed moves.
    sync_pitch: Option<f64>,
    /// The next synchronised line chains into the one after it.
    sync_chained: bool,
    /// G96 in force: its D cap (rpm).
    css_max_rpm: Option<f64>,
    /// M428 in force: lines are tool-tip moves.
    tool_centre_point: bool,
    pending: Option<Tagged<MachineBlock>>,
}

/// The nominal spindle speed of a G95 move under G96 without a cap (rpm): above any
/// spindle's.
const NO_CAP_RPM: f64 = 1e6;

impl CompensationStage {
    pub(crate) fn new(shared: Shared, default_blend_tolerance: f64) -> Self {
        CompensationStage {
            shared,
            mm_per_unit: 1.0,
            work: [0.0; AXES],
            g92: [0.0; AXES],
            rotation_deg: 0.0,
            tool: [0.0; AXES],
            feed_mm: 0.0,
            per_revolution: false,
            spindle_rpm: 0.0,
            mode: PathMode::ExactPath,
            default_blend_tolerance,
            sync_pitch: None,
            sync_chained: false,
            css_max_rpm: None,
            tool_centre_point: false,
            pending: None,
        }
    }

    pub(crate) fn body(&mut self, _ctx: &mut Context<'_>) -> Next {
        loop {
            if let Some(out) = self.pending.take() {
                if let Err(rejected) = self.shared.machine_blocks.try_put(out) {
                    self.pending = Some(rejected.value);
                    return Next::WaitFor {
                        trigger: self.shared.machine_blocks.space_trigger(),
                        timeout: None,
                    };
                }
            }
            let Some(Tagged { epoch, block }) = self.shared.program_blocks.try_get() else {
                return Next::Done;
            };
            if let Some(out) = self.convert(block) {
                self.pending = Some(Tagged { epoch, block: out });
            }
        }
    }

    /// Machine position (mm) of a program position.
    fn to_machine(&self, p: &[f64; AXES]) -> [f64; AXES] {
        let mut m = [0.0; AXES];
        for i in 0..AXES {
            m[i] = p[i] + self.g92[i];
        }
        if self.rotation_deg != 0.0 {
            let (s, c) = self.rotation_deg.to_radians().sin_cos();
            let (x, y) = (m[0], m[1]);
            m[0] = c * x - s * y;
            m[1] = s * x + c * y;
        }
        for i in 0..AXES {
            let linear = !(3..6).contains(&i);
            let scale = if linear { self.mm_per_unit } else { 1.0 };
            m[i] = (m[i] + self.work[i] + self.tool[i]) * scale;
        }
        m
    }

    fn feed(&self) -> Feed {
        let mm = self.feed_mm;
        if self.per_revolution {
            // Under G96 the speed changes along the move: it is planned at the cap (a speed
            // no spindle passes when there is none), and the kernel scales its feed by
            // the measured speed over it every period.
            let rpm = match self.css_max_rpm {
                Some(cap) if cap > 0.0 && cap <= NO_CAP_RPM => cap,
                Some(_) => NO_CAP_RPM,
                None => self.spindle_rpm.abs(),
            };
            Feed::PerRevolution {
                mm_per_rev: mm,
                spindle_rev_per_s: rpm / 60.0,
            }
        } else {
            Feed::UnitsPerSecond(mm / 60.0)
        }
    }

    fn convert(&mut self, block: ProgramBlock) -> Option<MachineBlock> {
        // It comes right before the line it is about (and is forgotten otherwise).
        let chained = std::mem::take(&mut self.sync_chained);
        match block {
            ProgramBlock::Units(mm) => self.mm_per_unit = mm,
            ProgramBlock::WorkOffset(o) => self.work = o,
            ProgramBlock::G92Offset(o) => self.g92 = o,
            ProgramBlock::Rotation(r) => self.rotation_deg = r,
            ProgramBlock::ToolOffset(o) => self.tool = o,
            ProgramBlock::FeedRate {
                rate,
                per_revolution,
            } => {
                self.feed_mm = rate * self.mm_per_unit;
                self.per_revolution = per_revolution;
            }
            ProgramBlock::PathMode(m) => self.mode = self.path_mode(m),
            ProgramBlock::SpindleSync(pitch) => {
                self.sync_pitch = pitch.map(|p| p * self.mm_per_unit);
            }
            ProgramBlock::SyncChained => self.sync_chained = true,
            ProgramBlock::ToolCentrePoint(on) => self.tool_centre_point = on,
            ProgramBlock::Line { line, end, rapid } => {
                return Some(self.line(line, &end, rapid, chained));
            }
            ProgramBlock::RigidTap { line, end, scale } => {
                return Some(MachineBlock::Synced {
                    line,
                    end: self.to_machine(&end),
                    pitch: self.sync_pitch.unwrap_or(0.0),
                    tap: Some(scale),
                    chained: false,
                });
            }
            ProgramBlock::Arc {
                line,
                end,
                centre,
                normal,
                turns,
                radius_tolerance,
            } => return Some(self.arc(line, &end, centre, normal, turns, radius_tolerance)),
            ProgramBlock::Probe { line, end, kind } => {
                let end = self.to_machine(&end);
                return Some(MachineBlock::Probe {
                    mv: Move {
                        kind: MoveKind::Line { end, rapid: false },
                        feed: self.feed(),
                        mode: PathMode::ExactStop,
                        line,
                    },
                    kind,
                });
            }
            ProgramBlock::Spline { line, end, control } => {
                return Some(self.spline(line, &end, control));
            }
            ProgramBlock::Dwell { line, seconds } => {
                return Some(MachineBlock::Motion(Move::dwell(seconds, line)));
            }
            ProgramBlock::Aux { line, aux } => {
                let aux = self.aux(aux);
                return Some(MachineBlock::Aux { line, aux });
            }
            ProgramBlock::End { line } => return Some(MachineBlock::End { line }),
            ProgramBlock::Error { line, code } => return Some(MachineBlock::Error { line, code }),
            ProgramBlock::MdiDone => return Some(MachineBlock::MdiDone),
        }
        None
    }

    /// G64 P and Q are lengths in the program's units when they were given. Plain G64 (P0),
    /// LinuxCNC's "best speed" without a bound, is the machine file's tolerance.
    fn path_mode(&self, m: PathMode) -> PathMode {
        match m {
            PathMode::Blend {
                tolerance,
                merge_tolerance,
            } => PathMode::Blend {
                tolerance: if tolerance > 0.0 {
                    tolerance * self.mm_per_unit
                } else {
                    self.default_blend_tolerance
                },
                merge_tolerance: merge_tolerance * self.mm_per_unit,
            },
            other => other,
        }
    }

    /// A line: of the tool's tip under TCP, synchronised with the spindle under G33 (a
    /// feed move; `chained` to the one before), or a plain move.
    fn line(&self, line: u32, end: &[f64; AXES], rapid: bool, chained: bool) -> MachineBlock {
        // The interpreter task lets only lines and arcs through under TCP.
        if self.tool_centre_point {
            return MachineBlock::TcpMove {
                line,
                path: TipPath::Line,
                end: self.to_machine(end),
                rapid,
                feed: self.feed(),
                mode: self.mode,
                tool_offset: self.tool[2] * self.mm_per_unit,
            };
        }
        if !rapid && self.sync_pitch.is_some() {
            return MachineBlock::Synced {
                line,
                end: self.to_machine(end),
                pitch: self.sync_pitch.unwrap_or(0.0),
                tap: None,
                chained,
            };
        }
        let end = self.to_machine(end);
        MachineBlock::Motion(Move {
            kind: MoveKind::Line { end, rapid },
            feed: if rapid {
                Feed::UnitsPerSecond(f64::INFINITY)
            } else {
                self.feed()
            },
            mode: self.mode,
            line,
        })
    }

    /// An arc (its centre and normal in program coordinates), of the tool's tip under TCP.
    fn arc(
        &self,
        line: u32,
        end: &[f64; AXES],
        centre: [f64; 3],
        normal: [f64; 3],
        turns: u32,
        radius_tolerance: f64,
    ) -> MachineBlock {
        let end_m = self.to_machine(end);
        let mut c = [0.0; AXES];
        c[..3].copy_from_slice(&centre);
        let c = self.to_machine(&c);
        let mut n = normal;
        if self.rotation_deg != 0.0 {
            let (s, co) = self.rotation_deg.to_radians().sin_cos();
            n = [
                co * normal[0] - s * normal[1],
                s * normal[0] + co * normal[1],
                normal[2],
            ];
        }
        if self.tool_centre_point {
            return MachineBlock::TcpMove {
                line,
                path: TipPath::Arc {
                    centre: [c[0], c[1], c[2]],
                    normal: n,
                    turns,
                },
                end: end_m,
                rapid: false,
                feed: self.feed(),
                mode: self.mode,
                tool_offset: self.tool[2] * self.mm_per_unit,
            };
        }
        MachineBlock::Motion(Move {
            kind: MoveKind::Arc {
                end: end_m,
                centre: [c[0], c[1], c[2]],
                normal: n,
                turns,
                radius_tolerance: radius_tolerance * self.mm_per_unit,
            },
            feed: self.feed(),
            mode: self.mode,
            line,
        })
    }

    fn spline(&self, line: u32, end: &[f64; AXES], control: Bezier) -> MachineBlock {
        // A Bézier curve is affine invariant: offsets, rotation and units apply to its
        // control points.
        let control = match control {
            Bezier::Quadratic(c) => Bezier::Quadratic(self.to_machine(&c)),
            Bezier::Cubic([c1, c2]) => Bezier::Cubic([self.to_machine(&c1), self.to_machine(&c2)]),
        };
        MachineBlock::Motion(Move {
            kind: MoveKind::Spline {
                end: self.to_machine(end),
                control,
            },
            feed: self.feed(),
            mode: self.mode,
            line,
        })
    }

    /// An auxiliary function: the spindle's speed is kept for feeds per revolution, and a
    /// constant surface speed is made machine units.
    fn aux(&mut self, aux: Aux) -> Aux {
        match aux {
            Aux::SpindleOn { rpm } | Aux::SpindleSpeed { rpm } => {
                self.spindle_rpm = rpm;
                aux
            }
            Aux::SpindleOff => {
                self.spindle_rpm = 0.0;
                aux
            }
            Aux::SurfaceSpeedOff => {
                self.css_max_rpm = None;
                aux
            }
            // LinuxCNC's canon: rpm = S (in mm/min) / (2π·|X − the X offsets|).
            Aux::SurfaceSpeed { surface, max_rpm } => {
                self.css_max_rpm = Some(max_rpm);
                let mm_per_minute = if self.mm_per_unit == 1.0 {
                    surface * 1000.0
                } else {
                    surface * 12.0 * self.mm_per_unit
                };
                Aux::ConstantSurfaceSpeed {
                    factor: mm_per_minute / std::f64::consts::TAU,
                    x_centre: (self.work[0] + self.g92[0] + self.tool[0]) * self.mm_per_unit,
                    max_rpm,
                }
            }
            _ => aux,
        }
    }
}
