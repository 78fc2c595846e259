//! Modal settings that move the coordinate frame: units, cutter and tool length
//! compensation, work coordinate systems, G10, G28/G30, G52/G92.

use crate::block::{AXES, Block, fmt_code, gg};
use crate::canon::{CanonCommand as C, CompensationSide, Plane, Pose, ToolEntry, Units};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::{Interpreter, rotate};
use crate::params::sys;

type Res<T> = Result<T, GcodeError>;

impl Interpreter {
    pub(crate) fn set_units(&mut self, units: Units) {
        self.emit(C::UseLengthUnits(units));
        if units == self.state.units {
            return;
        }
        let f = self.state.units.mm_per_unit() / units.mm_per_unit();
        let scale = |p: &mut Pose| {
            p.x *= f;
            p.y *= f;
            p.z *= f;
            p.u *= f;
            p.v *= f;
            p.w *= f;
        };
        let s = &mut self.state;
        scale(&mut s.position);
        scale(&mut s.g5x);
        scale(&mut s.g92);
        scale(&mut s.tool_offset);
        s.units = units;
    }

    pub(crate) fn cutter_comp(&mut self, b: &Block) -> Res<()> {
        let code = b.g[gg::CUTTER];
        if code == 400 {
            self.emit(C::StopCutterRadiusCompensation);
            self.state.cutter = None;
            self.state.cutter_gcode = 400;
            return Ok(());
        }
        if self.state.plane != Plane::XY && self.state.plane != Plane::XZ {
            return Err(self.g_err(
                b,
                gg::CUTTER,
                ErrorKind::State,
                "cutter radius compensation is allowed only in the XY and XZ planes",
            ));
        }
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::CUTTER,
                ErrorKind::State,
                "cutter radius compensation is already on (give G40 first)",
            ));
        }
        let mut side = if code == 410 || code == 411 {
            CompensationSide::Left
        } else {
            CompensationSide::Right
        };
        let (mut radius, orientation) = if code == 411 || code == 421 {
            let Some(d) = b.get(b'd') else {
                return Err(self.g_err(
                    b,
                    gg::CUTTER,
                    ErrorKind::MissingWord,
                    format!("G{} needs a D word (tool diameter)", fmt_code(code)),
                ));
            };
            let orientation = match b.get(b'l') {
                Some(l) => {
                    if self.state.plane != Plane::XZ {
                        return Err(self.err(
                            b,
                            b'l',
                            ErrorKind::State,
                            format!("G{} with an L word needs the G18 plane", fmt_code(code)),
                        ));
                    }
                    l.round() as i32
                }
                None => 0,
            };
            (d / 2.0, orientation)
        } else {
            let tool = match b.get(b'd') {
                Some(d) => {
                    let t = self.whole(b, b'd', d)?;
                    if t < 0 {
                        return Err(self.err(
                            b,
                            b'd',
                            ErrorKind::BadValue,
                            "negative D word (tool number)",
                        ));
                    }
                    t
                }
                None => self.state.current_tool,
            };
            let entry = if tool == 0 && b.get(b'd').is_none() {
                self.tools.get(self.state.current_tool).cloned()
            } else {
                if tool != 0
                    && self.tools.get(tool).is_none()
                    && !self.settings.accept_unknown_tools
                {
                    return Err(self.err(
                        b,
                        b'd',
                        ErrorKind::BadValue,
                        format!("tool {tool} is not in the tool table"),
                    ));
                }
                self.tools.get(tool).cloned()
            };
            let (dia, orientation) = entry.map_or((0.0, 0), |t| (t.diameter, t.orientation));
            if self.state.plane != Plane::XZ && orientation != 0 && orientation != 9 {
                return Err(self.g_err(
                    b,
                    gg::CUTTER,
                    ErrorKind::State,
                    format!("G{} with a lathe tool needs the G18 plane", fmt_code(code)),
                ));
            }
            (self.user_to_program(dia) / 2.0, orientation)
        };
        if radius < 0.0 {
            radius = -radius;
            side = match side {
                CompensationSide::Left => CompensationSide::Right,
                CompensationSide::Right => CompensationSide::Left,
            };
        }
        self.emit(C::StartCutterRadiusCompensation {
            side,
            radius,
            orientation,
        });
        self.state.cutter = Some(side);
        self.state.cutter_gcode = code;
        Ok(())
    }

    pub(crate) fn tool_length(&mut self, b: &Block) -> Res<()> {
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::LENGTH,
                ErrorKind::State,
                "cannot change the tool length offset with cutter radius compensation on",
            ));
        }
        let code = b.g[gg::LENGTH];
        let new = match code {
            490 => Pose::ZERO,
            430 | 432 => {
                if code == 432 && !b.has(b'h') {
                    // G43.2 with axis words: add them to the offset in force.
                    let mut v = self.state.tool_offset.to_array();
                    for (i, l) in AXES.iter().enumerate() {
                        if let Some(x) = b.get(*l) {
                            v[i] += x;
                        }
                    }
                    return self.apply_tool_offset(Pose::from_array(v), code);
                }
                let tool = match b.get(b'h') {
                    Some(h) => {
                        let t = self.whole(b, b'h', h)?;
                        if t < 0 {
                            return Err(self.err(b, b'h', ErrorKind::BadValue, "negative H word"));
                        }
                        if t != 0
                            && self.tools.get(t).is_none()
                            && !self.settings.accept_unknown_tools
                        {
                            return Err(self.err(
                                b,
                                b'h',
                                ErrorKind::BadValue,
                                format!("tool {t} is not in the tool table"),
                            ));
                        }
                        // H0 means the tool in the spindle.
                        if t == 0 { self.state.current_tool } else { t }
                    }
                    None => self.state.current_tool,
                };
                let off = self
                    .tools
                    .get(tool)
                    .map_or(Pose::ZERO, |t| t.offset)
                    .to_array();
                let mut v = [0.0; 9];
                for i in 0..9 {
                    v[i] = if (3..6).contains(&i) {
                        off[i]
                    } else {
                        self.user_to_program(off[i])
                    };
                }
                if code == 432 {
                    // G43.2 H: add that tool's offsets to the ones in force.
                    let cur = self.state.tool_offset.to_array();
                    for i in 0..9 {
                        v[i] += cur[i];
                    }
                }
                Pose::from_array(v)
            }
            _ => {
                // G43.1: offsets given directly.
                let mut v = self.state.tool_offset.to_array();
                for (i, l) in AXES.iter().enumerate() {
                    if let Some(x) = b.get(*l) {
                        v[i] = x;
                    }
                }
                Pose::from_array(v)
            }
        };
        self.apply_tool_offset(new, code)
    }

    /// Puts a tool length offset in force; the program position moves so that the machine
    /// does not.
    fn apply_tool_offset(&mut self, new: Pose, code: i32) -> Res<()> {
        self.emit(C::UseToolLengthOffset(new));
        let old = self.state.tool_offset;
        let (dx, dy) = rotate(old.x - new.x, old.y - new.y, -self.state.rotation);
        let mut p = self.state.position.to_array();
        let (o, n) = (old.to_array(), new.to_array());
        for i in 2..9 {
            p[i] += o[i] - n[i];
        }
        p[0] += dx;
        p[1] += dy;
        self.state.position = Pose::from_array(p);
        self.state.tool_offset = new;
        self.state.length_gcode = code;
        Ok(())
    }

    pub(crate) fn select_coord_system(&mut self, index: u8) {
        if index == self.state.origin_index {
            self.emit(C::Comment(
                "interpreter: continuing to use same coordinate system".into(),
            ));
            return;
        }
        let machine = self.machine_position();
        self.state.origin_index = index;
        self.params.set(sys::COORD_SYSTEM, f64::from(index));
        self.state.g5x = self.coord_system_from_params(index);
        self.state.rotation = self.params.get(sys::G54 + 20 * usize::from(index - 1) + 9);
        self.state.position = self.program_from_machine(&machine);
        self.emit(C::SetG5xOffset {
            index,
            offset: self.state.g5x,
        });
        self.emit(C::SetG92Offset(self.state.g92));
        self.emit(C::SetXyRotation(self.state.rotation));
    }

    pub(crate) fn g10(&mut self, b: &Block) -> Res<()> {
        let Some(l) = b.get(b'l') else {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::MissingWord,
                "G10 needs an L word (L1, L2, L10, L11 or L20)",
            ));
        };
        let l = l.round() as i32;
        let p = b.get(b'p').unwrap_or(0.0);
        let p_int = p.round() as i32;
        if (p - f64::from(p_int)).abs() > 0.0002 {
            return Err(self.err(
                b,
                b'p',
                ErrorKind::BadValue,
                "P value not an integer with G10",
            ));
        }
        match l {
            2 | 20 => {
                if !(0..=9).contains(&p_int) {
                    return Err(self.err(
                        b,
                        b'p',
                        ErrorKind::BadValue,
                        format!("P value out of range (0-9) with G10 L{l}"),
                    ));
                }
                self.g10_coord(b, l, p_int as u8)
            }
            1 | 10 | 11 => {
                if p_int < 1 {
                    return Err(self.err(
                        b,
                        b'p',
                        ErrorKind::BadValue,
                        format!("P value out of range with G10 L{l}"),
                    ));
                }
                self.g10_tool(b, l, p_int)
            }
            _ => Err(self.err(
                b,
                b'l',
                ErrorKind::BadValue,
                "G10 needs L1, L2, L10, L11 or L20",
            )),
        }
    }

    pub(crate) fn g10_coord(&mut self, b: &Block, l: i32, p: u8) -> Res<()> {
        if b.has(b'i') || b.has(b'j') {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::UnusedWord,
                "I and J words are not allowed with G10 L2",
            ));
        }
        let index = if p == 0 { self.state.origin_index } else { p };
        if self.state.cutter.is_some() && index == self.state.origin_index {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::State,
                "cannot change the active coordinate system with cutter radius compensation on",
            ));
        }
        let base = sys::G54 + 20 * usize::from(index - 1);
        // Current position as seen in that system.
        let machine = self.machine_position();
        let mut cur = self.coord_system_from_params(index);
        let rot_p = self.params.get(base + 9);
        {
            let s = &self.state;
            let mut c = machine.to_array();
            let off = cur.to_array();
            let g92 = s.g92.to_array();
            let tool = s.tool_offset.to_array();
            for i in 0..9 {
                c[i] -= off[i] + tool[i];
            }
            let (x, y) = rotate(c[0], c[1], -rot_p);
            c[0] = x;
            c[1] = y;
            for i in 0..9 {
                c[i] -= g92[i];
            }
            cur = Pose::from_array(c);
        }
        let r = if let Some(r) = b.get(b'r') {
            if l == 20 {
                return Err(self.err(
                    b,
                    b'r',
                    ErrorKind::UnusedWord,
                    "R is not allowed in G10 L20",
                ));
            }
            self.params.set(base + 9, r);
            r
        } else {
            rot_p
        };
        let mut off = self.pose_from_params(base).to_array();
        let cur_a = cur.to_array();
        if l == 20 {
            let (mut x, mut y) = (cur.x, cur.y);
            if let Some(v) = b.get(b'x') {
                x = v;
            }
            if let Some(v) = b.get(b'y') {
                y = v;
            }
            let (ox, oy) = rotate(cur.x, cur.y, r);
            let (nx, ny) = rotate(x, y, r);
            off[0] += ox - nx;
            off[1] += oy - ny;
            for (i, letter) in AXES.iter().enumerate().skip(2) {
                if let Some(v) = b.get(*letter) {
                    off[i] += cur_a[i] - v;
                }
            }
        } else {
            for (i, letter) in AXES.iter().enumerate() {
                if let Some(v) = b.get(*letter) {
                    off[i] = v;
                }
            }
        }
        let off = Pose::from_array(off);
        self.pose_to_params(base, &off);
        if index == self.state.origin_index {
            // The program position moves with the origin as LinuxCNC moves it: rotated
            // without the G92 offset (unlike a change of coordinate system).
            let old = self.state.g5x.to_array();
            let new = off.to_array();
            let mut p = self.state.position.to_array();
            let (x, y) = rotate(p[0], p[1], self.state.rotation);
            p[0] = x;
            p[1] = y;
            for i in 0..9 {
                p[i] += old[i] - new[i];
            }
            let (x, y) = rotate(p[0], p[1], -r);
            p[0] = x;
            p[1] = y;
            self.state.position = Pose::from_array(p);
            self.state.g5x = off;
            self.state.rotation = r;
            self.emit(C::SetG5xOffset { index, offset: off });
            self.emit(C::SetXyRotation(r));
        } else {
            self.emit(C::Comment(
                "interpreter: setting coordinate system origin".into(),
            ));
        }
        Ok(())
    }

    pub(crate) fn g10_tool(&mut self, b: &Block, l: i32, tool_no: i32) -> Res<()> {
        let known = self.tools.get(tool_no).cloned().or_else(|| {
            self.settings
                .accept_unknown_tools
                .then(|| crate::tools::Tool::new(tool_no, tool_no))
        });
        let Some(existing) = known else {
            return Err(self.err(
                b,
                b'p',
                ErrorKind::BadValue,
                format!("tool {tool_no} is not in the tool table"),
            ));
        };
        if !(b.has_axis() || b.has(b'r') || b.has(b'q') || b.has(b'i') || b.has(b'j')) {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::MissingWord,
                format!("G10 L{l} without offsets has no effect"),
            ));
        }
        let mut tool = existing;
        let mut off = tool.offset.to_array();
        if l == 1 {
            for (i, letter) in AXES.iter().enumerate() {
                if let Some(v) = b.get(*letter) {
                    off[i] = if (3..6).contains(&i) {
                        v
                    } else {
                        self.program_to_user(v)
                    };
                }
            }
        } else {
            // L10: offset such that the current point would read the given value with this
            // tool's offset in force; L11: the same in G59.3 (LinuxCNC's fixture system).
            let system = if l == 11 { 9 } else { self.state.origin_index };
            let base = sys::G54 + 20 * usize::from(system - 1);
            let sys_off = self.coord_system_from_params(system).to_array();
            let mut t = self.machine_position().to_array();
            for i in 0..9 {
                t[i] -= sys_off[i];
            }
            let (x, y) = rotate(t[0], t[1], -self.params.get(base + 9));
            t[0] = x;
            t[1] = y;
            if l == 10 && self.params.get(sys::G92_APPLIED) != 0.0 {
                let g92 = self.pose_from_params(sys::G92).to_array();
                for i in 0..9 {
                    t[i] -= g92[i];
                }
            }
            for (i, letter) in AXES.iter().enumerate() {
                if let Some(v) = b.get(*letter) {
                    let o = t[i] - v;
                    off[i] = if (3..6).contains(&i) {
                        o
                    } else {
                        self.program_to_user(o)
                    };
                }
            }
        }
        tool.offset = Pose::from_array(off);
        if let Some(r) = b.get(b'r') {
            tool.diameter = self.program_to_user(r * 2.0);
        }
        if let Some(i) = b.get(b'i') {
            tool.front_angle = i;
        }
        if let Some(j) = b.get(b'j') {
            tool.back_angle = j;
        }
        if let Some(q) = b.get(b'q') {
            tool.orientation = q.round() as i32;
        }
        let entry = ToolEntry {
            pocket: tool.pocket,
            tool: tool.number,
            offset: tool.offset,
            diameter: tool.diameter,
            front_angle: tool.front_angle,
            back_angle: tool.back_angle,
            orientation: tool.orientation,
        };
        let loaded = tool.pocket == self.state.current_pocket;
        self.tools.set(tool);
        self.emit(C::SetToolTableEntry(Box::new(entry)));
        if loaded {
            // The spindle's copy (pocket 0) changes too.
            self.emit(C::SetToolTableEntry(Box::new(ToolEntry {
                pocket: 0,
                ..entry
            })));
        }
        if tool_no == self.state.current_tool {
            self.set_tool_params();
        }
        Ok(())
    }

    pub(crate) fn go_home(&mut self, b: &Block) -> Res<()> {
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::State,
                "cannot use G28 or G30 with cutter radius compensation on",
            ));
        }
        let mid = self.find_ends(b);
        self.emit(C::StraightTraverse(mid));
        self.state.position = mid;
        let base = if b.g[gg::NON_MODAL] == 280 {
            sys::G28
        } else {
            sys::G30
        };
        let home_machine = {
            let mut v = [0.0; 9];
            for (i, x) in v.iter_mut().enumerate() {
                let p = self.params.get(base + i);
                *x = if (3..6).contains(&i) {
                    p
                } else {
                    self.user_to_program(p)
                };
            }
            Pose::from_array(v)
        };
        let home = self.program_from_machine(&home_machine).to_array();
        let mut end = mid.to_array();
        let any = b.has_axis();
        for (i, letter) in AXES.iter().enumerate() {
            if !any || b.has(*letter) {
                end[i] = home[i];
            }
        }
        let end = Pose::from_array(end);
        self.emit(C::StraightTraverse(end));
        self.state.position = end;
        Ok(())
    }

    pub(crate) fn g92(&mut self, b: &Block) -> Res<()> {
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::State,
                "cannot change axis offsets with cutter radius compensation on",
            ));
        }
        let code = b.g[gg::NON_MODAL];
        let mut pos = self.state.position.to_array();
        let mut off = self.state.g92.to_array();
        match code {
            520 => {
                // G52: a local offset given directly (it shares the G92 offset).
                self.params.set(sys::G92_APPLIED, 1.0);
                self.state.g92_applied = true;
                for (i, letter) in AXES.iter().enumerate() {
                    if let Some(v) = b.get(*letter) {
                        pos[i] += off[i] - v;
                        off[i] = v;
                    }
                }
            }
            920 => {
                self.params.set(sys::G92_APPLIED, 1.0);
                self.state.g92_applied = true;
                for (i, letter) in AXES.iter().enumerate() {
                    if let Some(v) = b.get(*letter) {
                        off[i] += pos[i] - v;
                        pos[i] = v;
                    }
                }
            }
            921 | 922 => {
                self.params.set(sys::G92_APPLIED, 0.0);
                self.state.g92_applied = false;
                for i in 0..9 {
                    pos[i] += off[i];
                    off[i] = 0.0;
                }
                if code == 921 {
                    for i in 0..9 {
                        self.params.set(sys::G92 + i, 0.0);
                    }
                }
            }
            _ => {
                self.params.set(sys::G92_APPLIED, 1.0);
                self.state.g92_applied = true;
                let saved = self.pose_from_params(sys::G92).to_array();
                for i in 0..9 {
                    pos[i] += off[i] - saved[i];
                }
                off = saved;
            }
        }
        self.state.position = Pose::from_array(pos);
        self.state.g92 = Pose::from_array(off);
        self.emit(C::SetG92Offset(self.state.g92));
        if code == 920 || code == 520 {
            let g92 = self.state.g92;
            self.pose_to_params(sys::G92, &g92);
        }
        Ok(())
    }
}
