"""Models of the rtcnc API, generated from docs/openapi.json by
scripts/gen_python_models.py. Do not edit: regenerate."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field

API_VERSION = "0.1.0"


class Ack(BaseModel):
    """A command's acknowledgement."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    code: str | None = Field(default=None, description="The refusal's or failure's code.")
    latency_ns: int | None = Field(default=None, description="For urgent commands: ns from the write to the kernel acting.")
    latency_periods: int | None = Field(default=None, description="For urgent commands: servo periods from the write to the kernel acting.")
    message: str | None = Field(default=None, description="Its message.")
    serial: int = Field(description="The command's serial.")
    state: str = Field(description="`pending`, `accepted`, `done`, `refused`, `failed`.")

class ApiInfo(BaseModel):
    """Version and limits of this API."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    axes: list[str] = Field(description="Axis letters.")
    jog_keep_alive_s: float = Field(description="Continuous jog keep-alive period, s.")
    machine: str = Field(description="The machine's name.")
    max_upload_bytes: int = Field(description="Largest upload, bytes.")
    max_ws_message_bytes: int = Field(description="Largest WebSocket message from a client, bytes.")
    servo_period_s: float = Field(description="Servo period, s.")
    version: str = Field(description="rtcnc version.")

AxisMap = dict[str, float]
"""Values by axis letter (only the machine's axes), e.g. `{"X": 1.5, "Y": 0}`."""

class AxisRef(BaseModel):
    """An axis."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    axis: str = Field(description="Axis letter.")

class CoolantRequest(BaseModel):
    """Coolant (an MDI M7/M8/M9 line)."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    flood: bool = Field(description="Flood.")
    mist: bool = Field(description="Mist.")

class CycleStart(BaseModel):
    """Start of a program."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    from_line: int | None = Field(default=None, description="Run from this line (0: from the start).")

class Estimate(BaseModel):
    """A cycle-time estimate from the planner in virtual time."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    computed_in_s: float = Field(description="Host seconds the simulation took.")
    cycle_time_s: float = Field(description="Seconds from cycle start to the end (what `rtcnc sim` prints).")
    ended: bool = Field(description="The program reached its end.")
    faults: list[str] = Field(description="Faults, as codes.")

class Event(BaseModel):
    """One event."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    ack: str | None = Field(default=None, description="For `ack`: `accepted`, `done`, `refused`, `failed`.")
    code: str | None = Field(default=None, description="Stable code: the acknowledgement's refusal, the fault's (`kernel.estop`), or the new state.")
    cycle: int = Field(description="Servo cycle.")
    joint: str | None = Field(default=None, description="Joint name.")
    kind: str = Field(description="`ack`, `fault`, `message`, `state`, `program_end`, `client_lost`, `machine_lost`, `machine_attached`, `events_lost`.")
    latency_ns: int | None = Field(default=None, description="For an urgent command's `ack`: ns from the write to the kernel acting.")
    latency_periods: int | None = Field(default=None, description="For an urgent command's `ack`: servo periods from the client's write to the kernel acting (1 = the next period).")
    line: int | None = Field(default=None, description="Program line.")
    message: str = Field(description="Text for a person.")
    seq: int = Field(description="The API's sequence number (1, 2, …; kept across machine restarts).")
    serial: int | None = Field(default=None, description="For `ack`: the command's serial.")
    time_s: float = Field(description="Machine time, s.")
    value: float | None = Field(default=None, description="A value (following error, …).")

class EventPage(BaseModel):
    """Events after a sequence number."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    events: list[Event] = Field(description="The events, oldest first.")
    last_seq: int = Field(description="The newest sequence number (ask again with `since` = this).")
    missed: int = Field(description="Events older than `since` that the API no longer keeps.")

class FaultAck(BaseModel):
    """Acknowledge faults."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    up_to_seq: int = Field(description="Every fault up to this sequence number.")

class FaultRecord(BaseModel):
    """A fault in the history."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    acknowledged: bool = Field(description="Acknowledged by an operator.")
    code: str = Field(description="Stable code.")
    joint: str | None = Field(default=None, description="Joint.")
    line: int | None = Field(default=None, description="Program line.")
    message: str = Field(description="Message.")
    seq: int = Field(description="The event's sequence number (acknowledge up to it).")
    time_s: float = Field(description="Machine time, s.")

class HandwheelRequest(BaseModel):
    """The handwheel (manual pulse generator): which axis it moves and its scale."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    axis: str | None = Field(default=None, description="Axis letter; absent or null releases the handwheel.")
    scale: float | None = Field(default=None, description="Multiplier of the machine's `handwheel.units_per_count` (×1, ×10, ×100).")

class Jog(BaseModel):
    """A jog."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    axis: str = Field(description="Axis letter.")
    distance: float | None = Field(default=None, description="Incremental: signed distance, units.")
    velocity: float | None = Field(default=None, description="Continuous: signed velocity, units/s (needs a keep-alive every 200 ms).")

class Joint(BaseModel):
    """One joint."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    feedback: float = Field(description="Feedback position.")
    following_error: float = Field(description="Following error the servo loop saw in its last period.")
    homed: bool = Field(description="Homed.")
    name: str = Field(description="Its name.")
    setpoint: float = Field(description="Set-point.")
    velocity: float = Field(description="Velocity (feedback), units/s.")

class Lease(BaseModel):
    """The control lease."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    holder: str | None = Field(default=None, description="The holder's user name.")
    mine: bool = Field(description="Held by the caller's session.")

class LinkCounters(BaseModel):
    """Link counters."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    client_losses: int = Field(description="Times the machine lost its API process.")
    events_dropped: int = Field(description="Events the machine dropped (ring full).")
    trace_dropped: int = Field(description="Trace samples dropped.")

class LoadProgram(BaseModel):
    """A program to load."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    name: str = Field(description="Name in the program store.")

class Login(BaseModel):
    """Log-in."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    password: str = Field(description="Password.")
    user: str = Field(description="User name.")

class MachineFile(BaseModel):
    """The machine file."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    changed_since_start: bool = Field(description="The file differs from the one the API process started with: the machine process takes the new one at its next start.")
    handwheel_units_per_count: float = Field(description="Travel per handwheel count at ×1 (`[handwheel] units_per_count`), in the file the API process started with.")
    path: str = Field(description="Its path on the machine's computer.")
    text: str = Field(description="Its text (TOML).")

class MachineFileSaved(BaseModel):
    """A machine file written."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    applies_at_next_start: bool = Field(description="Always true: the machine process reads its file only when it starts.")
    size: int = Field(description="Bytes written.")

class Mdi(BaseModel):
    """An MDI line."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    line: str = Field(description="The line (at most 256 bytes).")

class Modal(BaseModel):
    """The interpreter's modal state."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    feed_rate: float = Field(description="F, program units per minute.")
    g92_offset: AxisMap = Field(description="G92 offset.")
    g_codes: list[str] = Field(description="Active G codes (`G1`, `G17`, `G54`, `G64`, …).")
    m_codes: list[str] = Field(description="Active M codes.")
    rotation: float = Field(description="XY rotation, degrees.")
    speed: float = Field(description="S, rpm.")
    tool_offset: AxisMap = Field(description="Tool length offset.")
    units: str = Field(description="`mm` or `inch`.")
    work_offset: AxisMap = Field(description="Work offset in force, program units.")
    work_system: str = Field(description="`G54` .. `G59.3`.")

ModeName = str
"""The machine's mode."""

class ModeRequest(BaseModel):
    """A mode switch."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    mode: ModeName = Field(description="The mode.")

class Overrides(BaseModel):
    """Overrides, as factors (1 = 100 %)."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    feed: float = Field(description="Feed, 0..2.")
    rapid: float = Field(description="Rapid, 0..1.")
    spindle: float = Field(description="Spindle, 0.5..1.5.")

class OverridesRequest(BaseModel):
    """Overrides to set (absent: unchanged)."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    feed: float | None = Field(default=None, description="Feed, 0..2.")
    rapid: float | None = Field(default=None, description="Rapid, 0..1.")
    spindle: float | None = Field(default=None, description="Spindle, 0.5..1.5.")

class PasswordChange(BaseModel):
    """A password change."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    new: str = Field(description="The new one (at least 8 characters).")
    old: str = Field(description="The password now.")

class PlcForce(BaseModel):
    """A force."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    path: str = Field(description="Path.")
    value: str = Field(description="Value as IEC text.")

class PlcVariable(BaseModel):
    """A PLC variable."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    path: str = Field(description="Path (`GLOBAL`, `INSTANCE.VAR`, `timer.ET`, `word.3`).")
    value: str = Field(description="Value as IEC text (`TRUE`, `42`, `T#1s`).")

class PlcVariableInfo(BaseModel):
    """A variable of the PLC program."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    location: str | None = Field(default=None, description="Direct address of a located variable (`%IX0.1`).")
    path: str = Field(description="Path (`GLOBAL`, `INSTANCE.VAR`, `A[3]`), as `GET /api/plc/variables/{path}` takes it.")
    retain: bool = Field(description="Declared RETAIN.")
    type_name: str = Field(description="IEC type (`BOOL`, `INT`, `TIME`, …).")

class PlcWatch(BaseModel):
    """The watch list."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    paths: list[str] = Field(description="Paths (at most 16); their values come in the status (`plc_watch`).")

class Polyline(BaseModel):
    """One polyline."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    kind: str = Field(description="`rapid` or `feed`.")
    lines: list[int] = Field(description="Program line of each point after the first.")
    points: list[list[float]] = Field(description="Points (X, Y, Z), mm, in the canonical frame (work offsets applied).")

class Preview(BaseModel):
    """A tool-path preview: the canonical motion as polylines."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    errors: list[ProgramError] = Field(description="Interpreter errors (the preview ends at the first).")
    max: list[float] = Field(description="Maximum.")
    min: list[float] = Field(description="Bounding box minimum (X, Y, Z), mm.")
    paths: list[Polyline] = Field(description="Polylines, each rapid or feed, in program order.")

class Problem(BaseModel):
    """An RFC 9457 problem document."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    code: str = Field(description="Stable code (`command.busy`, `kernel.estop`, `auth.forbidden`, …).")
    detail: str = Field(description="What happened, for a person.")
    extra: dict[str, Any] | None = Field(default=None, description="Details: a program's errors, the lease holder, the command serial.")
    status: int = Field(description="The HTTP status.")
    title: str = Field(description="Short summary of the kind of problem.")
    type_: str = Field(alias="type", description="`urn:rtcnc:problem:` followed by the code.")

class ProgramCheck(BaseModel):
    """The interpreter's verdict on a program text (nothing is stored)."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    errors: list[ProgramError] = Field(description="Every error (up to 100), with line and column; empty: the program is good.")
    lines: int = Field(description="Lines in the text.")

class ProgramError(BaseModel):
    """An interpreter error in an uploaded program."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    code: str = Field(description="Stable code (`gcode.…`).")
    column: int = Field(description="1-based column (0: the whole line).")
    line: int = Field(description="1-based line.")
    message: str = Field(description="Message.")

class ProgramInfo(BaseModel):
    """A program in the store."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    lines: int = Field(description="Lines.")
    name: str = Field(description="File name.")
    size: int = Field(description="Bytes.")

class SessionInfo(BaseModel):
    """A session."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    expires_in_s: int = Field(description="Seconds until the session expires.")
    holds_lease: bool = Field(description="This session holds the control lease.")
    password_change_required: bool = Field(description="The password is a one-time password: change it before anything else.")
    role: str = Field(description="`viewer`, `operator`, `setter`, `admin`.")
    token: str | None = Field(default=None, description="Bearer token (only in the log-in answer).")
    user: str = Field(description="User.")

class Spindle(BaseModel):
    """The spindle."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    command_rpm: float = Field(description="Commanded speed (after the override and G96), rpm.")
    direction: str = Field(description="`cw`, `ccw` or `off`.")
    on: bool = Field(description="Commanded on.")
    rpm: float = Field(description="Measured speed, rpm.")

class SpindleRequest(BaseModel):
    """The spindle (an MDI M3/M4/M5 line: needs the machine idle)."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    direction: str = Field(description="`cw`, `ccw` or `off`.")
    rpm: float | None = Field(default=None, description="rpm (for cw/ccw).")

class Status(BaseModel):
    """The machine's status snapshot."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    analog_inputs: list[float] = Field(description="Analogue inputs.")
    block_delete: bool = Field(description="Block delete on.")
    connected: bool = Field(description="The machine process answers (false: every other field is the last known).")
    cycle: int = Field(description="Servo cycles run.")
    deadline_misses: int = Field(description="Deadline misses of the real-time tasks so far.")
    digital_inputs: int = Field(description="Digital inputs, bit n = input n.")
    digital_outputs: int = Field(description="Digital outputs.")
    distance_to_go: AxisMap = Field(description="Distance to go: from the machine position to the end of the executing program or MDI line (its path as planned), per axis, mm or degrees; zero in manual motion and at rest.")
    estop_input: bool = Field(description="The e-stop input is pressed.")
    fault_count: int = Field(description="Faults raised since the machine started.")
    flood: bool = Field(description="Flood coolant on.")
    hold: str | None = Field(default=None, description="What holds the machine while `state` is `held`: `machine_logic` (it asks for a feed hold: the door open, a fault, the spindle not at speed; a resume is refused until it stops asking, and a program it held at its start goes on by itself then), `feed_stop_switch` (M53; goes on when released), `resume` (a feed hold waits for the operator's resume); none otherwise.")
    hold_message: str | None = Field(default=None, description="The operator's message of `hold`, e.g. `held: machine logic requests a feed hold (door open?)`.")
    joints: list[Joint] = Field(description="Per joint.")
    last_fault: str | None = Field(default=None, description="The last fault's code (`kernel.estop`, …).")
    lease_holder: str | None = Field(default=None, description="Who holds the control lease.")
    line: int = Field(description="Program line executing.")
    link: LinkCounters = Field(description="Link counters.")
    logic_hold: bool = Field(description="The machine logic holds the feed (door open, fault).")
    machine: str = Field(description="The machine's name.")
    machine_position: AxisMap = Field(description="Machine position (set-point), mm or degrees.")
    mist: bool = Field(description="Mist coolant on.")
    modal: Modal | None = Field(default=None)
    mode: str = Field(description="`manual`, `auto`, `mdi`.")
    optional_stop: bool = Field(description="Optional stop (M1) on.")
    overrides: Overrides = Field(description="Overrides.")
    path_speed: float = Field(description="Path speed, units/s.")
    plc_watch: list[WatchValue] = Field(description="Watched PLC variables.")
    program: str | None = Field(default=None, description="The loaded program's name.")
    program_ended: bool = Field(description="The program reached its end.")
    ready: bool = Field(description="Drives enabled, ready for commands.")
    single_block: bool = Field(description="Single block on.")
    spindle: Spindle = Field(description="Spindle.")
    state: str = Field(description="`starting`, `estop`, `idle`, `running`, `held`, `paused`, `waiting_for_logic`, `fault`.")
    time_s: float = Field(description="Machine time, s since its start.")
    tool: int = Field(description="Tool in the spindle.")
    work_position: AxisMap = Field(description="Work position (program coordinates: work offset, G92, tool length offset and XY rotation taken off), program units.")

class Switch(BaseModel):
    """On or off."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    on: bool = Field(description="On.")

class TaskTiming(BaseModel):
    """One task's timing (the executive's monitor)."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    activations: int = Field(description="Body runs.")
    deadline_misses: int = Field(description="Deadline misses.")
    execution_max_us: float = Field(description="Largest, µs.")
    execution_mean_us: float = Field(description="Execution time mean, µs.")
    execution_p99_us: float = Field(description="p99, µs.")
    lateness_max_us: float = Field(description="Largest, µs.")
    lateness_p99_us: float = Field(description="Wake-up latency p99, µs.")
    name: str = Field(description="Name.")
    skipped_releases: int = Field(description="Skipped releases.")

class Timing(BaseModel):
    """Task timing."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    fifo: bool = Field(description="The real-time threads run SCHED_FIFO.")
    tasks: list[TaskTiming] = Field(description="Per task.")
    underruns: int = Field(description="Servo periods without a fresh set-point so far.")

class Tool(BaseModel):
    """A tool (LinuxCNC `.tbl` meaning; lengths in machine units)."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    back_angle: float | None = Field(default=None, description="J: lathe back angle.")
    comment: str | None = Field(default=None, description="Comment.")
    diameter: float = Field(description="D.")
    front_angle: float | None = Field(default=None, description="I: lathe front angle.")
    number: int = Field(description="T.")
    offset: AxisMap = Field(description="Offsets (X, Y, Z, A, B, C, U, V, W; Z is the length on a mill).")
    orientation: int | None = Field(default=None, description="Q: lathe orientation.")
    pocket: int = Field(description="P: pocket.")

class WatchValue(BaseModel):
    """A watched PLC variable."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    forced: bool = Field(description="Forced.")
    path: str = Field(description="Its path.")
    value: float = Field(description="Value (BOOL as 0/1).")

class WorkOffset(BaseModel):
    """A work offset (G54..G59.3), program units."""
    model_config = ConfigDict(extra="allow", populate_by_name=True)

    offset: AxisMap = Field(description="Offset per axis.")
    rotation: float | None = Field(default=None, description="XY rotation, degrees.")
    system: str = Field(description="`G54` .. `G59.3`.")

Ack.model_rebuild()
ApiInfo.model_rebuild()
AxisRef.model_rebuild()
CoolantRequest.model_rebuild()
CycleStart.model_rebuild()
Estimate.model_rebuild()
Event.model_rebuild()
EventPage.model_rebuild()
FaultAck.model_rebuild()
FaultRecord.model_rebuild()
HandwheelRequest.model_rebuild()
Jog.model_rebuild()
Joint.model_rebuild()
Lease.model_rebuild()
LinkCounters.model_rebuild()
LoadProgram.model_rebuild()
Login.model_rebuild()
MachineFile.model_rebuild()
MachineFileSaved.model_rebuild()
Mdi.model_rebuild()
Modal.model_rebuild()
ModeRequest.model_rebuild()
Overrides.model_rebuild()
OverridesRequest.model_rebuild()
PasswordChange.model_rebuild()
PlcForce.model_rebuild()
PlcVariable.model_rebuild()
PlcVariableInfo.model_rebuild()
PlcWatch.model_rebuild()
Polyline.model_rebuild()
Preview.model_rebuild()
Problem.model_rebuild()
ProgramCheck.model_rebuild()
ProgramError.model_rebuild()
ProgramInfo.model_rebuild()
SessionInfo.model_rebuild()
Spindle.model_rebuild()
SpindleRequest.model_rebuild()
Status.model_rebuild()
Switch.model_rebuild()
TaskTiming.model_rebuild()
Timing.model_rebuild()
Tool.model_rebuild()
WatchValue.model_rebuild()
WorkOffset.model_rebuild()
