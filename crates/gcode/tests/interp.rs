//! Behaviour of the interpreter API beyond what rs274 can check: U/V/W axes, PRINT,
//! error positions, MDI, parameter persistence, the endless-loop guard, memory bookkeeping
//! of loops. Expected values are worked out by hand.

use rtcnc_gcode::canon::{CanonCommand, Pose, Units};
use rtcnc_gcode::{ErrorKind, GcodeError, Interpreter, Parameters, Settings, ToolTable};

fn interp() -> Interpreter {
    Interpreter::new(Settings::default(), ToolTable::new(), Parameters::new())
}

/// Runs `text`, returns the commands after the 6 start-up ones, and the error if any.
fn run(text: &str) -> (Vec<CanonCommand>, Option<GcodeError>) {
    let mut it = interp();
    it.open_text("test.ngc", text).unwrap();
    let mut out = Vec::new();
    let mut error = None;
    for c in &mut it {
        match c {
            Ok(c) => out.push(c.command),
            Err(e) => {
                error = Some(e);
                break;
            }
        }
    }
    (out.split_off(6), error)
}

fn text(c: &CanonCommand) -> String {
    let mut v = Vec::new();
    rtcnc_gcode::Canon {
        source: Default::default(),
        command: c.clone(),
    }
    .write_rs274(&mut v, false);
    String::from_utf8(v).unwrap()
}

#[test]
fn uvw_axes_move_and_print_nine_coordinates() {
    let (out, err) = run("G1 X1 U2 V3 W4 F100\nM2\n");
    assert!(err.is_none());
    let feed = out
        .iter()
        .find(|c| matches!(c, CanonCommand::StraightFeed(_)))
        .unwrap();
    assert_eq!(
        *feed,
        CanonCommand::StraightFeed(Pose {
            x: 1.0,
            u: 2.0,
            v: 3.0,
            w: 4.0,
            ..Pose::ZERO
        })
    );
    assert_eq!(
        text(feed),
        "STRAIGHT_FEED(1.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 2.0000, 3.0000, 4.0000)\n"
    );
}

#[test]
fn print_comments_substitute_and_stay_out_of_the_rs274_text() {
    let (out, _) = run("#1=2.5\n#<_x1>=3\n(PRINT, a=#1 b=#<_x1> c=#<nope>)\nM2\n");
    let print = out
        .iter()
        .find(|c| matches!(c, CanonCommand::Print(_)))
        .unwrap();
    assert_eq!(
        *print,
        CanonCommand::Print(" a=2.500000 b=3.000000 c=######".into())
    );
    assert_eq!(text(print), "");
}

#[test]
fn errors_name_file_line_and_column() {
    let (_, err) = run("G0 X0\nG1 X1 Q1 F100\n");
    let e = err.unwrap();
    assert_eq!(e.kind, ErrorKind::UnusedWord);
    assert_eq!((&*e.file, e.line, e.column), ("test.ngc", 2, 7));
    assert_eq!(e.to_string().split(": ").next(), Some("test.ngc:2:7"));
    let (_, err) = run("G0 X[1 + / 2]\n");
    let e = err.unwrap();
    assert_eq!((e.kind, e.line, e.column), (ErrorKind::Syntax, 1, 10));
    let (_, err) = run("G1 X1\n");
    assert_eq!(err.unwrap().message, "cannot do G1 with zero feed rate");
}

#[test]
fn unterminated_blocks_are_reported_at_their_opening_line() {
    let (_, err) = run("G0 X1\no7 while [1 lt 0]\nG0 X2\nM2\n");
    let e = err.unwrap();
    assert_eq!((e.kind, e.line), (ErrorKind::Flow, 2));
    let (_, err) = run("o<nothere> call\nM2\n");
    assert_eq!(err.unwrap().kind, ErrorKind::Flow);
}

#[test]
fn mdi_lines_keep_the_modal_state() {
    let mut it = interp();
    let _: Vec<_> = (&mut it).collect();
    it.execute_mdi("G20 G91 F10").unwrap();
    it.execute_mdi("G1 X1").unwrap();
    it.execute_mdi("G1 X1").unwrap();
    let cmds: Vec<CanonCommand> = (&mut it).map(|c| c.unwrap().command).collect();
    assert_eq!(cmds[0], CanonCommand::SetFeedRate(10.0));
    assert_eq!(cmds[1], CanonCommand::UseLengthUnits(Units::Inches));
    let feeds: Vec<f64> = cmds
        .iter()
        .filter_map(|c| match c {
            CanonCommand::StraightFeed(p) => Some(p.x),
            _ => None,
        })
        .collect();
    assert_eq!(feeds, vec![1.0, 2.0]);
    assert_eq!(it.modal_state().units, Units::Inches);
    assert!(!it.modal_state().absolute);
}

#[test]
fn work_offsets_persist_through_the_parameter_file() {
    let dir = std::env::temp_dir().join(format!("rtcnc-gcode-persist-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let var = dir.join("machine.var");
    let mut it = interp();
    it.open_text("a.ngc", "G10 L2 P2 X5 Y-2.5 R30\nG55\nG92 X1\nM2\n")
        .unwrap();
    for c in &mut it {
        c.unwrap();
    }
    it.parameters().save(&var).unwrap();
    let params = Parameters::load(&var).unwrap();
    assert_eq!(params.get(5241), 5.0);
    assert_eq!(params.get(5242), -2.5);
    assert_eq!(params.get(5250), 30.0);
    // In G55 (rotated 30 degrees, origin X5 Y-2.5) the machine origin reads
    // X = -5 cos 30 + 2.5 sin 30 = -3.080127, so G92 X1 offsets X by -4.080127.
    assert_eq!(params.get(5211), -4.080127);
    // M2 selects G54 again, so the next run starts there, with the G92 offset in force.
    assert_eq!(params.get(5220), 1.0);
    let mut next = Interpreter::new(Settings::default(), ToolTable::new(), params);
    let start: Vec<CanonCommand> = (&mut next).map(|c| c.unwrap().command).collect();
    assert_eq!(
        start[2],
        CanonCommand::SetG92Offset(Pose {
            x: -4.080127,
            ..Pose::ZERO
        })
    );
    next.open_text("b.ngc", "G55\nM2\n").unwrap();
    let cmds: Vec<CanonCommand> = (&mut next).map(|c| c.unwrap().command).collect();
    assert_eq!(
        cmds[0],
        CanonCommand::SetG5xOffset {
            index: 2,
            offset: Pose {
                x: 5.0,
                y: -2.5,
                ..Pose::ZERO
            }
        }
    );
    assert_eq!(cmds[2], CanonCommand::SetXyRotation(30.0));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn endless_loops_without_output_are_stopped() {
    let mut it = Interpreter::new(
        Settings {
            max_lines_without_output: 1000,
            ..Settings::default()
        },
        ToolTable::new(),
        Parameters::new(),
    );
    it.open_text("loop.ngc", "o1 while [1]\n#1=[#1+1]\no1 endwhile\nM2\n")
        .unwrap();
    let last = (&mut it).last().unwrap();
    assert_eq!(last.unwrap_err().kind, ErrorKind::Flow);
}

#[test]
fn long_loops_and_calls_keep_no_history() {
    // 20 000 iterations calling a subroutine: the output is complete and in order.
    let (out, err) = run(
        "o<step> sub\nG1 X#1\no<step> endsub\nF100\n#2=0\no1 repeat [20000]\n#2=[#2+1]\no<step> call [#2]\no1 endrepeat\nM2\n",
    );
    assert!(err.is_none(), "{err:?}");
    let xs: Vec<f64> = out
        .iter()
        .filter_map(|c| match c {
            CanonCommand::StraightFeed(p) => Some(p.x),
            _ => None,
        })
        .collect();
    assert_eq!(xs.len(), 20_000);
    assert_eq!(xs[0], 1.0);
    assert_eq!(xs[19_999], 20_000.0);
}

#[test]
fn g10_l1_changes_the_tool_table() {
    let mut tools = ToolTable::new();
    tools.set(rtcnc_gcode::Tool::new(3, 3));
    let mut it = Interpreter::new(Settings::default(), tools, Parameters::new());
    it.open_text("t.ngc", "G10 L1 P3 Z-12.5 R2\nM2\n").unwrap();
    for c in &mut it {
        c.unwrap();
    }
    let t = it.tool_table().get(3).unwrap();
    assert_eq!(t.offset.z, -12.5);
    assert_eq!(t.diameter, 4.0);
}

#[test]
fn cutter_compensation_start_carries_the_radius() {
    let mut tools = ToolTable::new();
    let mut t = rtcnc_gcode::Tool::new(1, 1);
    t.diameter = 6.0;
    tools.set(t);
    let mut it = Interpreter::new(Settings::default(), tools, Parameters::new());
    it.open_text("c.ngc", "T1 M6\nG41\nG40\nG42.1 D4\nM2\n")
        .unwrap();
    let cmds: Vec<CanonCommand> = (&mut it).map(|c| c.unwrap().command).collect();
    let starts: Vec<(f64, rtcnc_gcode::canon::CompensationSide)> = cmds
        .iter()
        .filter_map(|c| match c {
            CanonCommand::StartCutterRadiusCompensation { side, radius, .. } => {
                Some((*radius, *side))
            }
            _ => None,
        })
        .collect();
    use rtcnc_gcode::canon::CompensationSide::*;
    assert_eq!(starts, vec![(3.0, Left), (2.0, Right)]);
}

#[test]
fn probing_waits_for_the_machine_when_asked_to() {
    let mut it = Interpreter::new(
        Settings {
            wait_for_machine: true,
            ..Settings::default()
        },
        ToolTable::new(),
        Parameters::new(),
    );
    it.open_text(
        "p.ngc",
        "F100\nG38.2 Z-10\nG0 Z[#5063 + 1]\n(debug,#5070)\nM66 P1 L3 Q2\nG0 X#5399\nM2\n",
    )
    .unwrap();
    let before: Vec<CanonCommand> = (&mut it).map(|c| c.unwrap().command).collect();
    assert!(it.is_waiting());
    assert_eq!(before.last(), Some(&CanonCommand::TurnProbeOff));
    // The probe tripped at Z-4 (machine), the machine stopped at Z-3.9.
    let z = |z| Pose { z, ..Pose::ZERO };
    it.probe_result(z(-4.0), true, z(-3.9));
    let after: Vec<CanonCommand> = (&mut it).map(|c| c.unwrap().command).collect();
    assert_eq!(after[0], CanonCommand::StraightTraverse(z(-3.0)));
    assert_eq!(after[1], CanonCommand::Message("1.000000".into()));
    assert!(it.is_waiting());
    it.input_result(7.0);
    let rest: Vec<CanonCommand> = (&mut it).map(|c| c.unwrap().command).collect();
    assert_eq!(
        rest[0],
        CanonCommand::StraightTraverse(Pose {
            x: 7.0,
            z: -3.0,
            ..Pose::ZERO
        })
    );
}

#[test]
fn g52_shifts_the_local_origin() {
    let (out, err) = run("G52 X10\nG0 X1\nG52 X0\nG0 X1\nM2\n");
    assert!(err.is_none());
    let traverses: Vec<f64> = out
        .iter()
        .filter_map(|c| match c {
            CanonCommand::StraightTraverse(p) => Some(p.x),
            _ => None,
        })
        .collect();
    // Program coordinates stay as written; the offset goes out as SET_G92_OFFSET(10, ...).
    assert_eq!(traverses, vec![1.0, 1.0]);
    assert_eq!(
        out[0],
        CanonCommand::SetG92Offset(Pose {
            x: 10.0,
            ..Pose::ZERO
        })
    );
}

#[test]
fn mdi_calls_subroutines_from_the_search_path_and_abort_stops_a_program() {
    let dir = std::env::temp_dir().join(format!("rtcnc-gcode-mdi-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("probe_x.ngc"),
        "o<probe_x> sub\nG0 X#1\nG0 Y#2\no<probe_x> endsub\n",
    )
    .unwrap();
    let mut it = Interpreter::new(
        Settings {
            subroutine_path: vec![dir.clone()],
            ..Settings::default()
        },
        ToolTable::new(),
        Parameters::new(),
    );
    let _: Vec<_> = (&mut it).collect();
    it.execute_mdi("o<probe_x> call [3] [4]").unwrap();
    assert!(it.is_running());
    let cmds: Vec<CanonCommand> = (&mut it).map(|c| c.unwrap().command).collect();
    assert_eq!(
        cmds,
        vec![
            CanonCommand::StraightTraverse(Pose {
                x: 3.0,
                ..Pose::ZERO
            }),
            CanonCommand::StraightTraverse(Pose {
                x: 3.0,
                y: 4.0,
                ..Pose::ZERO
            }),
        ]
    );
    assert!(!it.is_running());
    it.open_text("long.ngc", "G0 X1\nG0 X2\nG0 X3\nM2\n")
        .unwrap();
    assert!(it.next_canon().is_some());
    it.abort();
    assert!(it.next_canon().is_none());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn g43_2_with_axis_words_adds_to_the_offset_in_force() {
    // rs274 (2.9.0~pre1) rejects this form ("Requested tool -1"): checked by hand.
    let (out, err) = run("G43.1 Z2\nG43.2 Z0.5 X0.1\nM2\n");
    assert!(err.is_none(), "{err:?}");
    assert_eq!(
        out[1],
        CanonCommand::UseToolLengthOffset(Pose {
            x: 0.1,
            z: 2.5,
            ..Pose::ZERO
        })
    );
}

#[test]
fn continue_in_a_do_loop_goes_to_its_while_test() {
    // rs274 (2.9) instead takes the closing `while` for the start of a new while loop and
    // leaves the do loop: a documented difference. By hand: X1, (2 skipped), X3, X4, break.
    let (out, err) = run(
        "#1=0\no1 do\n#1=[#1+1]\no2 if [#1 eq 2]\no1 continue\no2 endif\nG1 F100 X#1\no3 if [#1 ge 4]\no1 break\no3 endif\no1 while [#1 lt 10]\nG1 Y1\nM2\n",
    );
    assert!(err.is_none(), "{err:?}");
    let xs: Vec<(f64, f64)> = out
        .iter()
        .filter_map(|c| match c {
            CanonCommand::StraightFeed(p) => Some((p.x, p.y)),
            _ => None,
        })
        .collect();
    assert_eq!(xs, vec![(1.0, 0.0), (3.0, 0.0), (4.0, 0.0), (4.0, 1.0)]);
}

#[test]
fn unknown_tools_are_refused_unless_accepted() {
    let (_, err) = run("T5 M6\nM2\n");
    assert_eq!(err.unwrap().message, "tool 5 is not in the tool table");
    let mut it = Interpreter::new(
        Settings {
            accept_unknown_tools: true,
            ..Settings::default()
        },
        ToolTable::new(),
        Parameters::new(),
    );
    it.open_text("t.ngc", "T5 M6\nG43 H5\nM2\n").unwrap();
    let cmds: Vec<CanonCommand> = (&mut it).map(|c| c.unwrap().command).collect();
    assert!(cmds.contains(&CanonCommand::ChangeTool(5)));
    assert!(cmds.contains(&CanonCommand::UseToolLengthOffset(Pose::ZERO)));
    assert_eq!(it.modal_state().current_tool, 5);
}

#[test]
fn user_m_codes_go_to_the_machine_logic_with_p_and_q() {
    let (out, err) = run("M100 P1 Q2.5\nM199\nM2\n");
    assert!(err.is_none());
    assert_eq!(
        out[0],
        CanonCommand::UserMCode {
            code: 100,
            p: Some(1.0),
            q: Some(2.5)
        }
    );
    assert_eq!(text(&out[0]), "USER_M_CODE(100, 1.0000, 2.5000)\n");
    assert_eq!(text(&out[1]), "USER_M_CODE(199, -1.0000, -1.0000)\n");
}

#[test]
fn canned_cycles_work_in_the_uvw_planes() {
    // G81 in G17.1 (UV plane, W drills) from W5 with R1: worked out by hand.
    let (out, err) = run("G17.1\nG0 W5\nG81 U1 V2 W-1 R1 F100\nG80\nG17\nM2\n");
    assert!(err.is_none(), "{err:?}");
    let moves: Vec<(bool, f64, f64, f64)> = out
        .iter()
        .filter_map(|c| match c {
            CanonCommand::StraightTraverse(p) => Some((false, p.u, p.v, p.w)),
            CanonCommand::StraightFeed(p) => Some((true, p.u, p.v, p.w)),
            _ => None,
        })
        .collect();
    assert_eq!(
        moves,
        vec![
            (false, 0.0, 0.0, 5.0),
            (false, 1.0, 2.0, 5.0),
            (false, 1.0, 2.0, 1.0),
            (true, 1.0, 2.0, -1.0),
            (false, 1.0, 2.0, 1.0),
        ]
    );
    let (_, err) = run("G17.1\nG81 U1 V2 W-1 R1 X1 F100\n");
    assert_eq!(err.unwrap().kind, ErrorKind::UnusedWord);
}

#[test]
fn an_inverse_time_spline_gets_the_rate_of_its_length() {
    // The parabola (10t, 20t(1-t)) is y = 2x - x²/5 over x in [0, 10]; its length is
    // 2.5 (2√5 + asinh 2) mm. With G93 F2 it takes 1/2 minute: rate = 2 · length.
    let (out, err) = run("G21 G17 G90 G0 X0 Y0\nG93 G5.1 I5 J10 X10 Y0 F2\nM2\n");
    assert!(err.is_none(), "{err:?}");
    let at = out
        .iter()
        .position(|c| matches!(c, CanonCommand::SplineFeed(_)))
        .unwrap();
    let CanonCommand::SetFeedRate(rate) = out[at - 1] else {
        panic!("no feed rate before the spline: {:?}", &out[..at]);
    };
    let length = 2.5 * (2.0 * 5f64.sqrt() + 2f64.asinh());
    assert!((rate - 2.0 * length).abs() <= 1e-9, "{rate}");
}

#[test]
fn a_spline_may_not_move_other_axes() {
    let (_, err) = run("G21 G17 F100\nG5.1 I1 J1 X2 Y0 U1\nM2\n");
    let e = err.unwrap();
    assert_eq!(e.kind, ErrorKind::UnusedWord);
    assert!(e.message.contains("U, V or W"), "{}", e.message);
}

#[test]
fn m428_and_m429_switch_tool_centre_point_control() {
    let (out, err) = run("G0 X1\nM428\nG1 X2 F100\nM429\nM2\n");
    assert!(err.is_none(), "{err:?}");
    let switches: Vec<&CanonCommand> = out
        .iter()
        .filter(|c| matches!(c, CanonCommand::SetToolCentrePoint(_)))
        .collect();
    assert_eq!(
        switches,
        [
            &CanonCommand::SetToolCentrePoint(true),
            &CanonCommand::SetToolCentrePoint(false)
        ]
    );
    assert_eq!(text(switches[0]), "SET_TOOL_CENTRE_POINT(ON)\n");
    assert_eq!(text(switches[1]), "SET_TOOL_CENTRE_POINT(OFF)\n");

    // The modal state follows; M2 switches it off.
    let mut it = interp();
    it.execute_mdi("M428").unwrap();
    while let Some(Ok(_)) = it.next_canon() {}
    assert!(it.modal_state().tool_centre_point);
    it.execute_mdi("M2").unwrap();
    while let Some(Ok(_)) = it.next_canon() {}
    assert!(!it.modal_state().tool_centre_point);
}

#[test]
fn m428_takes_no_axis_words_nor_cutter_compensation() {
    // G0 in force: X1 would be a move on the same line.
    let (_, err) = run("G0 X0\nM428 X1\nM2\n");
    let err = err.expect("refused");
    assert_eq!(
        (err.kind, err.line, err.column),
        (ErrorKind::Conflict, 2, 1)
    );
    assert!(err.message.contains("M428 takes no axis words"), "{err}");
    let (_, err) = run("G0 X0 Y0\nG41.1 D2\nG1 X10 F100\nM429\nM2\n");
    let err = err.expect("refused");
    assert_eq!((err.kind, err.line), (ErrorKind::State, 4));
}

/// The kernel tells the interpreter where the machine stands after the switch: the
/// program position is that machine position less the offsets.
#[test]
fn kinematics_switched_moves_the_program_position() {
    let mut it = interp();
    it.execute_mdi("G10 L2 P1 X5").unwrap();
    while let Some(Ok(_)) = it.next_canon() {}
    it.execute_mdi("G54").unwrap();
    while let Some(Ok(_)) = it.next_canon() {}
    it.kinematics_switched(Pose {
        x: 12.0,
        y: 3.0,
        z: 1.0,
        ..Pose::ZERO
    });
    assert_eq!(it.modal_state().position.x, 7.0);
    assert_eq!(it.machine_position_now().x, 12.0);
}
