//! The endpoints. Every one is in the OpenAPI document (`crate::ApiDoc`).

use std::sync::Arc;
use std::time::Duration;

use axum::Json;
use axum::body::Bytes;
use axum::extract::{ConnectInfo, FromRequestParts, Path, Query, State};
use axum::http::request::Parts;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use rtcnc_kernel::link::Refusal;
use rtcnc_kernel::link::layout::{WireCommand, WireText, command, service, urgent};
use serde::Deserialize;
use utoipa::IntoParams;

use crate::App;
use crate::auth::{Role, Session};
use crate::models::*;
use crate::problem::{ApiResult, Problem};

/// The caller's session (from `Authorization: Bearer TOKEN`, or `?token=` on the
/// WebSocket).
pub struct Caller {
    /// The session.
    pub session: Session,
    /// Its token.
    pub token: String,
}

impl FromRequestParts<Arc<App>> for Caller {
    type Rejection = Problem;

    async fn from_request_parts(parts: &mut Parts, app: &Arc<App>) -> Result<Self, Problem> {
        let bearer = parts
            .headers
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.strip_prefix("Bearer "))
            .map(str::trim)
            .map(str::to_string);
        let token = bearer.or_else(|| {
            // Browsers cannot set headers on a WebSocket: the token may come in the query.
            parts.uri.query().and_then(|q| {
                q.split('&')
                    .find_map(|kv| kv.strip_prefix("token="))
                    .map(str::to_string)
            })
        });
        let session = app.auth.session(token.as_deref())?;
        Ok(Caller {
            session,
            token: token.unwrap_or_default(),
        })
    }
}

impl Caller {
    fn viewer(&self) -> ApiResult<()> {
        self.session.require(Role::Viewer)
    }
}

// ----- session and lease ---------------------------------------------------------------

/// Logs in.
#[utoipa::path(post, path = "/api/session", tag = "session", request_body = Login,
    responses((status = 200, body = SessionInfo),
        (status = 401, body = Problem, content_type = "application/problem+json"),
        (status = 429, body = Problem, content_type = "application/problem+json")))]
pub async fn login(
    State(app): State<Arc<App>>,
    ConnectInfo(crate::ClientAddr(from)): ConnectInfo<crate::ClientAddr>,
    Json(body): Json<Login>,
) -> ApiResult<Json<SessionInfo>> {
    let app2 = Arc::clone(&app);
    // argon2 takes tens of milliseconds: off the async threads.
    let (token, session) =
        tokio::task::spawn_blocking(move || app2.auth.login(from.ip(), &body.user, &body.password))
            .await
            .map_err(|e| Problem::internal(e.to_string()))??;
    Ok(Json(SessionInfo {
        token: Some(token),
        user: session.user.clone(),
        role: session.role.as_str().into(),
        expires_in_s: app.auth.expires_in(&session),
        password_change_required: session.must_change,
        holds_lease: false,
    }))
}

/// The caller's session.
#[utoipa::path(get, path = "/api/session", tag = "session", security(("bearer" = [])),
    responses((status = 200, body = SessionInfo),
        (status = 401, body = Problem, content_type = "application/problem+json")))]
pub async fn session_info(State(app): State<Arc<App>>, caller: Caller) -> Json<SessionInfo> {
    let s = &caller.session;
    Json(SessionInfo {
        token: None,
        user: s.user.clone(),
        role: s.role.as_str().into(),
        expires_in_s: app.auth.expires_in(s),
        password_change_required: s.must_change,
        holds_lease: app.auth.lease().is_some_and(|l| l.session == s.id),
    })
}

/// Logs out (and gives the lease back).
#[utoipa::path(delete, path = "/api/session", tag = "session", security(("bearer" = [])),
    responses((status = 204), (status = 401, body = Problem, content_type = "application/problem+json")))]
pub async fn logout(State(app): State<Arc<App>>, caller: Caller) -> StatusCode {
    app.auth.logout(&caller.token);
    StatusCode::NO_CONTENT
}

/// Changes the caller's password (required after the first admin's one-time password).
#[utoipa::path(post, path = "/api/session/password", tag = "session", security(("bearer" = [])),
    request_body = PasswordChange,
    responses((status = 204), (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn change_password(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(body): Json<PasswordChange>,
) -> ApiResult<StatusCode> {
    let app2 = Arc::clone(&app);
    tokio::task::spawn_blocking(move || {
        app2.auth
            .change_password(&caller.token, &body.old, &body.new)
    })
    .await
    .map_err(|e| Problem::internal(e.to_string()))??;
    Ok(StatusCode::NO_CONTENT)
}

/// Who holds the control lease.
#[utoipa::path(get, path = "/api/lease", tag = "session", security(("bearer" = [])),
    responses((status = 200, body = Lease)))]
pub async fn lease(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Json<Lease>> {
    caller.viewer()?;
    let l = app.auth.lease();
    Ok(Json(Lease {
        mine: l.as_ref().is_some_and(|l| l.session == caller.session.id),
        holder: l.map(|l| l.user),
    }))
}

/// Query of `POST /api/lease`.
#[derive(Debug, Deserialize, IntoParams)]
pub struct TakeOver {
    /// An admin takes the lease from whoever holds it.
    #[serde(default)]
    take_over: bool,
}

/// Takes the control lease (operator; `take_over=true`: admin, from another session).
#[utoipa::path(post, path = "/api/lease", tag = "session", security(("bearer" = [])), params(TakeOver),
    responses((status = 200, body = Lease),
        (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn acquire_lease(
    State(app): State<Arc<App>>,
    caller: Caller,
    Query(q): Query<TakeOver>,
) -> ApiResult<Json<Lease>> {
    app.auth.acquire(&caller.session, q.take_over)?;
    Ok(Json(Lease {
        holder: Some(caller.session.user.clone()),
        mine: true,
    }))
}

/// Gives the control lease back.
#[utoipa::path(delete, path = "/api/lease", tag = "session", security(("bearer" = [])),
    responses((status = 204), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn release_lease(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<StatusCode> {
    app.auth.release(&caller.session)?;
    Ok(StatusCode::NO_CONTENT)
}

// ----- status and events -----------------------------------------------------------------

/// This API: version, machine, limits.
#[utoipa::path(get, path = "/api", tag = "status", security(("bearer" = [])),
    responses((status = 200, body = ApiInfo)))]
pub async fn info(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Json<ApiInfo>> {
    caller.viewer()?;
    let meta = app.machine.meta();
    Ok(Json(ApiInfo {
        version: env!("CARGO_PKG_VERSION").into(),
        machine: meta.name.clone(),
        axes: meta.axes(),
        servo_period_s: meta.servo_period_s,
        max_upload_bytes: app.options.max_upload_bytes as u64,
        max_ws_message_bytes: crate::MAX_WS_MESSAGE as u64,
        jog_keep_alive_s: meta.jog_keep_alive_s,
    }))
}

/// The status snapshot.
#[utoipa::path(get, path = "/api/status", tag = "status", security(("bearer" = [])),
    responses((status = 200, body = Status),
        (status = 503, body = Problem, content_type = "application/problem+json")))]
pub async fn status(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Json<Status>> {
    caller.viewer()?;
    app.machine.client()?;
    Ok(Json(app.status_now()))
}

/// Query of `GET /api/events`: where to start.
#[derive(Debug, Deserialize, IntoParams)]
pub struct Since {
    /// Events after this sequence number (0: all the API keeps).
    #[serde(default)]
    since: u64,
    /// At most this many (default 1000).
    #[serde(default)]
    limit: Option<usize>,
}

/// Events after a sequence number.
#[utoipa::path(get, path = "/api/events", tag = "status", security(("bearer" = [])), params(Since),
    responses((status = 200, body = EventPage)))]
pub async fn events(
    State(app): State<Arc<App>>,
    caller: Caller,
    Query(q): Query<Since>,
) -> ApiResult<Json<EventPage>> {
    caller.viewer()?;
    Ok(Json(app.machine.events_since(
        q.since,
        q.limit.unwrap_or(1000).clamp(1, 10_000),
    )))
}

/// Query of a command: how long to wait for its acknowledgement.
#[derive(Debug, Deserialize, IntoParams)]
pub struct AckWait {
    /// Wait until the acknowledgement is `accepted` or later, or `done` (or refused, failed).
    #[serde(default)]
    until: Option<String>,
    /// Longest wait, ms (at most 60 000).
    #[serde(default)]
    timeout_ms: Option<u64>,
}

/// A command's acknowledgement, optionally waiting for it.
#[utoipa::path(get, path = "/api/commands/{serial}", tag = "control", security(("bearer" = [])),
    params(("serial" = u64, Path, description = "The command's serial"), AckWait),
    responses((status = 200, body = Ack), (status = 404, body = Problem, content_type = "application/problem+json")))]
pub async fn command_ack(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(serial): Path<u64>,
    Query(q): Query<AckWait>,
) -> ApiResult<Json<Ack>> {
    caller.viewer()?;
    let timeout = Duration::from_millis(q.timeout_ms.unwrap_or(0).min(60_000));
    let states: &[&str] = match q.until.as_deref() {
        Some("done") => &["done", "refused", "failed"],
        _ => &["accepted", "done", "refused", "failed"],
    };
    app.machine
        .wait_ack(serial, states, timeout)
        .await
        .map(Json)
        .ok_or_else(|| Problem::not_found("command.unknown_serial", "no command with this serial"))
}

// ----- control ---------------------------------------------------------------------------

fn refusal_problem(ack: &Ack) -> Problem {
    let code = ack.code.clone().unwrap_or_else(|| "command.refused".into());
    let unprocessable = code == Refusal::BadAxis.code() || code == Refusal::BadValue.code();
    let detail = ack.message.clone().unwrap_or_else(|| "refused".into());
    let p = if unprocessable {
        Problem::unprocessable(&code, detail)
    } else {
        Problem::conflict(&code, detail)
    };
    p.with_extra(serde_json::json!({ "serial": ack.serial }))
}

/// Sends a command and waits (up to a second) for the kernel to take or refuse it.
async fn run_command(app: &App, wire: WireCommand) -> ApiResult<Response> {
    let serial = app.machine.send(wire)?;
    finish(app, serial, false).await
}

async fn finish(app: &App, serial: u64, until_done: bool) -> ApiResult<Response> {
    let states: &[&str] = if until_done {
        &["done", "refused", "failed"]
    } else {
        &["accepted", "done", "refused", "failed"]
    };
    let wait = if until_done { 30 } else { 1 };
    let ack = app
        .machine
        .wait_ack(serial, states, Duration::from_secs(wait))
        .await
        .ok_or_else(|| Problem::internal("acknowledgement lost"))?;
    match ack.state.as_str() {
        "refused" | "failed" => Err(refusal_problem(&ack)),
        "pending" => Ok((StatusCode::ACCEPTED, Json(ack)).into_response()),
        _ => Ok(Json(ack).into_response()),
    }
}

fn wire(kind: u32) -> WireCommand {
    WireCommand {
        kind,
        ..WireCommand::default()
    }
}

async fn control(app: &App, caller: &Caller, wire: WireCommand) -> ApiResult<Response> {
    app.auth.require_lease(&caller.session)?;
    run_command(app, wire).await
}

async fn urgent_command(app: &App, kind: u32, axis: u32, value: f64) -> ApiResult<Response> {
    let serial = app.machine.send_urgent(kind, axis, value)?;
    finish(app, serial, false).await
}

/// Leaves e-stop or fault: resets the faults and enables the drives.
#[utoipa::path(post, path = "/api/control/reset", tag = "control", security(("bearer" = [])),
    responses((status = 200, body = Ack), (status = 202, body = Ack),
        (status = 401, body = Problem, content_type = "application/problem+json"),
        (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 503, body = Problem, content_type = "application/problem+json")))]
pub async fn reset(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Response> {
    control(&app, &caller, wire(command::RESET)).await
}

/// Emergency stop: every operator, with or without the lease.
#[utoipa::path(post, path = "/api/control/estop", tag = "control", security(("bearer" = [])),
    responses((status = 200, body = Ack), (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 503, body = Problem, content_type = "application/problem+json")))]
pub async fn estop(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Response> {
    caller.session.require(Role::Operator)?;
    urgent_command(&app, urgent::ESTOP, 0, 0.0).await
}

/// Feed hold: every operator, with or without the lease.
#[utoipa::path(post, path = "/api/control/feed-hold", tag = "control", security(("bearer" = [])),
    responses((status = 200, body = Ack), (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 503, body = Problem, content_type = "application/problem+json")))]
pub async fn feed_hold(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Response> {
    caller.session.require(Role::Operator)?;
    urgent_command(&app, urgent::FEED_HOLD, 0, 0.0).await
}

/// Resume after a feed hold, M0/M1 or single block.
#[utoipa::path(post, path = "/api/control/resume", tag = "control", security(("bearer" = [])),
    responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn resume(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Response> {
    app.auth.require_lease(&caller.session)?;
    urgent_command(&app, urgent::RESUME, 0, 0.0).await
}

/// Stop the program (abort): decelerate along the path, drop what is queued.
#[utoipa::path(post, path = "/api/control/stop", tag = "control", security(("bearer" = [])),
    responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn stop(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Response> {
    app.auth.require_lease(&caller.session)?;
    urgent_command(&app, urgent::ABORT, 0, 0.0).await
}

/// Loads a program of the store; the next cycle start runs it.
#[utoipa::path(post, path = "/api/control/program", tag = "control", security(("bearer" = [])),
    request_body = LoadProgram,
    responses((status = 200, body = Ack), (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn load_program(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(body): Json<LoadProgram>,
) -> ApiResult<Response> {
    app.auth.require_lease(&caller.session)?;
    let path = app.program_path(&body.name)?;
    if !path.is_file() {
        return Err(Problem::not_found(
            "program.not_found",
            format!("no program {}", body.name),
        ));
    }
    let mut w = wire(command::LOAD_PROGRAM);
    w.text = WireText::new(&path.to_string_lossy());
    if w.text.as_str() != path.to_string_lossy() {
        return Err(Problem::unprocessable(
            "program.path_too_long",
            "the program's path is longer than 256 bytes",
        ));
    }
    let r = run_command(&app, w).await?;
    app.machine.set_program(Some(body.name));
    Ok(r)
}

/// Cycle start: runs the loaded program (from a line: motion before it is skipped).
#[utoipa::path(post, path = "/api/control/cycle-start", tag = "control", security(("bearer" = [])),
    request_body = CycleStart,
    responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn cycle_start(
    State(app): State<Arc<App>>,
    caller: Caller,
    body: Option<Json<CycleStart>>,
) -> ApiResult<Response> {
    let mut w = wire(command::START);
    w.number = u64::from(body.map_or(0, |b| b.from_line));
    control(&app, &caller, w).await
}

fn switch(kind: u32, on: bool) -> WireCommand {
    let mut w = wire(kind);
    w.number = u64::from(on);
    w
}

/// Single block on or off.
#[utoipa::path(post, path = "/api/control/single-block", tag = "control", security(("bearer" = [])),
    request_body = Switch, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn single_block(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<Switch>,
) -> ApiResult<Response> {
    control(&app, &caller, switch(command::SINGLE_BLOCK, b.on)).await
}

/// Optional stop (M1) on or off.
#[utoipa::path(post, path = "/api/control/optional-stop", tag = "control", security(("bearer" = [])),
    request_body = Switch, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn optional_stop(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<Switch>,
) -> ApiResult<Response> {
    control(&app, &caller, switch(command::OPTIONAL_STOP, b.on)).await
}

/// Block delete (`/`) on or off, from the next program start.
#[utoipa::path(post, path = "/api/control/block-delete", tag = "control", security(("bearer" = [])),
    request_body = Switch, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn block_delete(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<Switch>,
) -> ApiResult<Response> {
    control(&app, &caller, switch(command::BLOCK_DELETE, b.on)).await
}

fn mdi_wire(line: &str) -> ApiResult<WireCommand> {
    let mut w = wire(command::MDI);
    w.text = WireText::new(line);
    if w.text.as_str() != line || line.contains('\n') {
        return Err(Problem::unprocessable(
            "command.bad_value",
            "an MDI line is one line of at most 256 bytes",
        ));
    }
    Ok(w)
}

/// One MDI line.
#[utoipa::path(post, path = "/api/control/mdi", tag = "control", security(("bearer" = [])),
    request_body = Mdi, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn mdi(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<Mdi>,
) -> ApiResult<Response> {
    control(&app, &caller, mdi_wire(&b.line)?).await
}

fn axis_of(app: &App, letter: &str) -> ApiResult<u32> {
    app.machine.meta().axis_index(letter).ok_or_else(|| {
        Problem::unprocessable(
            Refusal::BadAxis.code(),
            format!("no axis {letter} on this machine"),
        )
    })
}

/// Jog: continuous (`velocity`; send a keep-alive at least every 200 ms or it stops) or
/// incremental (`distance`).
#[utoipa::path(post, path = "/api/control/jog", tag = "control", security(("bearer" = [])),
    request_body = Jog, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn jog(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<Jog>,
) -> ApiResult<Response> {
    let axis = axis_of(&app, &b.axis)?;
    let mut w = match (b.velocity, b.distance) {
        (Some(v), None) => {
            let mut w = wire(command::JOG_CONTINUOUS);
            w.value = v;
            w
        }
        (None, Some(d)) => {
            let mut w = wire(command::JOG_INCREMENT);
            w.value = d;
            w
        }
        _ => {
            return Err(Problem::unprocessable(
                "command.bad_value",
                "give either velocity or distance",
            ));
        }
    };
    w.axis = axis;
    control(&app, &caller, w).await
}

/// Keeps a continuous jog going for another 200 ms.
#[utoipa::path(post, path = "/api/control/jog/keep-alive", tag = "control", security(("bearer" = [])),
    request_body = AxisRef, responses((status = 204), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn jog_keep_alive(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<AxisRef>,
) -> ApiResult<StatusCode> {
    app.auth.require_lease(&caller.session)?;
    let mut w = wire(command::JOG_KEEP_ALIVE);
    w.axis = axis_of(&app, &b.axis)?;
    app.machine.send(w)?;
    Ok(StatusCode::NO_CONTENT)
}

/// Stops a jog (through the urgent ring).
#[utoipa::path(post, path = "/api/control/jog/stop", tag = "control", security(("bearer" = [])),
    request_body = AxisRef, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn jog_stop(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<AxisRef>,
) -> ApiResult<Response> {
    app.auth.require_lease(&caller.session)?;
    let axis = axis_of(&app, &b.axis)?;
    urgent_command(&app, urgent::JOG_STOP, axis, 0.0).await
}

/// Homes every joint (in the configured sequence).
#[utoipa::path(post, path = "/api/control/home", tag = "control", security(("bearer" = [])),
    responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn home(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Response> {
    control(&app, &caller, wire(command::HOME_ALL)).await
}

/// Homes the joints of one axis (a gantry's together), whatever their sequence numbers;
/// the other axes keep their homed state.
#[utoipa::path(post, path = "/api/control/home/{axis}", tag = "control", security(("bearer" = [])),
    params(("axis" = String, Path, description = "Axis letter")),
    responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn home_axis(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(axis): Path<String>,
) -> ApiResult<Response> {
    let mut w = wire(command::HOME_AXIS);
    w.axis = axis_of(&app, &axis)?;
    control(&app, &caller, w).await
}

/// Switches the mode (manual, auto, MDI) while the machine is idle, as a mode key does;
/// cycle start, MDI, jog and homing still switch to the mode they need.
#[utoipa::path(post, path = "/api/control/mode", tag = "control", security(("bearer" = [])),
    request_body = ModeRequest, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn mode(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<ModeRequest>,
) -> ApiResult<Response> {
    let mut w = wire(command::SET_MODE);
    w.number = match b.mode {
        ModeName::Manual => 0,
        ModeName::Auto => 1,
        ModeName::Mdi => 2,
    };
    control(&app, &caller, w).await
}

/// The handwheel: puts it on an axis with a scale (×1, ×10, ×100 of the machine's
/// `handwheel.units_per_count` per count), or releases it (`axis` absent). Manual mode; the
/// machine must be idle.
#[utoipa::path(post, path = "/api/control/handwheel", tag = "control", security(("bearer" = [])),
    request_body = HandwheelRequest, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn handwheel(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<HandwheelRequest>,
) -> ApiResult<Response> {
    let mut w = wire(command::HANDWHEEL);
    w.axis = match b.axis.as_deref() {
        Some(letter) => axis_of(&app, letter)?,
        None => u32::MAX,
    };
    if !(b.scale.is_finite() && b.scale > 0.0) {
        return Err(Problem::unprocessable(
            "command.bad_value",
            "the scale is a number > 0",
        ));
    }
    w.value = b.scale;
    control(&app, &caller, w).await
}

/// Sets overrides (urgent: read by the next servo period).
#[utoipa::path(post, path = "/api/control/overrides", tag = "control", security(("bearer" = [])),
    request_body = OverridesRequest, responses((status = 200, body = Vec<Ack>), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn overrides(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<OverridesRequest>,
) -> ApiResult<Json<Vec<Ack>>> {
    app.auth.require_lease(&caller.session)?;
    let mut acks = Vec::new();
    for (kind, v) in [
        (urgent::FEED_OVERRIDE, b.feed),
        (urgent::RAPID_OVERRIDE, b.rapid),
        (urgent::SPINDLE_OVERRIDE, b.spindle),
    ] {
        if let Some(v) = v {
            if !v.is_finite() {
                return Err(Problem::unprocessable(
                    "command.bad_value",
                    "an override is a number",
                ));
            }
            let serial = app.machine.send_urgent(kind, 0, v)?;
            if let Some(a) = app
                .machine
                .wait_ack(
                    serial,
                    &["done", "refused", "failed"],
                    Duration::from_secs(1),
                )
                .await
            {
                acks.push(a);
            }
        }
    }
    Ok(Json(acks))
}

async fn mdi_lines(app: &App, caller: &Caller, lines: &[String]) -> ApiResult<Response> {
    app.auth.require_lease(&caller.session)?;
    let mut last = None;
    for line in lines {
        let serial = app.machine.send(mdi_wire(line)?)?;
        last = Some(finish(app, serial, true).await?);
    }
    last.ok_or_else(|| Problem::internal("no line"))
}

/// Spindle on (cw, ccw) at rpm, or off: an MDI line (M3/M4 S, M5), so the machine must be
/// idle.
#[utoipa::path(post, path = "/api/control/spindle", tag = "control", security(("bearer" = [])),
    request_body = SpindleRequest, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn spindle(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<SpindleRequest>,
) -> ApiResult<Response> {
    let rpm = b.rpm.unwrap_or(0.0);
    if !rpm.is_finite() || rpm < 0.0 {
        return Err(Problem::unprocessable(
            "command.bad_value",
            "rpm is a number >= 0",
        ));
    }
    let line = match b.direction.as_str() {
        "cw" => format!("M3 S{rpm}"),
        "ccw" => format!("M4 S{rpm}"),
        "off" => "M5".to_string(),
        _ => {
            return Err(Problem::unprocessable(
                "command.bad_value",
                "direction is cw, ccw or off",
            ));
        }
    };
    mdi_lines(&app, &caller, &[line]).await
}

/// Coolant: MDI lines (M9, then M7 and/or M8), so the machine must be idle.
#[utoipa::path(post, path = "/api/control/coolant", tag = "control", security(("bearer" = [])),
    request_body = CoolantRequest, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json")))]
pub async fn coolant(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<CoolantRequest>,
) -> ApiResult<Response> {
    let mut lines = vec!["M9".to_string()];
    if b.mist {
        lines.push("M7".into());
    }
    if b.flood {
        lines.push("M8".into());
    }
    mdi_lines(&app, &caller, &lines).await
}

// ----- programs --------------------------------------------------------------------------

/// The program store.
#[utoipa::path(get, path = "/api/programs", tag = "programs", security(("bearer" = [])),
    responses((status = 200, body = Vec<ProgramInfo>)))]
pub async fn list_programs(
    State(app): State<Arc<App>>,
    caller: Caller,
) -> ApiResult<Json<Vec<ProgramInfo>>> {
    caller.viewer()?;
    let mut out = Vec::new();
    let dir = std::fs::read_dir(&app.options.programs_dir)
        .map_err(|e| Problem::internal(e.to_string()))?;
    for entry in dir.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if crate::valid_program_name(&name) && entry.path().is_file() {
            let text = std::fs::read(entry.path()).unwrap_or_default();
            out.push(ProgramInfo {
                name,
                size: text.len() as u64,
                lines: text.iter().filter(|&&b| b == b'\n').count() as u64,
            });
        }
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(Json(out))
}

/// A program's text.
#[utoipa::path(get, path = "/api/programs/{name}", tag = "programs", security(("bearer" = [])),
    params(("name" = String, Path, description = "File name")),
    responses((status = 200, body = String, content_type = "text/plain"), (status = 404, body = Problem, content_type = "application/problem+json")))]
pub async fn read_program(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(name): Path<String>,
) -> ApiResult<Response> {
    caller.viewer()?;
    let text = app.read_program(&name)?;
    Ok(([(header::CONTENT_TYPE, "text/plain; charset=utf-8")], text).into_response())
}

/// A program's bytes as text: within the upload limit, UTF-8, no NUL byte.
fn program_text<'a>(app: &App, body: &'a [u8]) -> ApiResult<&'a str> {
    if body.len() > app.options.max_upload_bytes {
        return Err(Problem::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            "program.too_large",
            format!(
                "a program has at most {} bytes",
                app.options.max_upload_bytes
            ),
        ));
    }
    let text = std::str::from_utf8(body).map_err(|e| {
        Problem::unprocessable(
            "program.encoding",
            format!("not UTF-8 text: invalid byte at offset {}", e.valid_up_to()),
        )
    })?;
    if let Some(at) = text.find('\0') {
        return Err(Problem::unprocessable(
            "program.encoding",
            format!("a NUL byte at offset {at}"),
        ));
    }
    Ok(text)
}

/// Uploads a program (UTF-8 text, no NUL bytes, at most the upload limit). It is stored
/// only when the interpreter finds no error; otherwise every error comes back with its line
/// and column (422, `extra.errors`).
#[utoipa::path(put, path = "/api/programs/{name}", tag = "programs", security(("bearer" = [])),
    params(("name" = String, Path, description = "File name: letters, digits, '.', '_', '-'")),
    request_body(content = String, content_type = "text/plain"),
    responses((status = 201, body = ProgramInfo), (status = 413, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn upload_program(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(name): Path<String>,
    body: Bytes,
) -> ApiResult<Response> {
    caller.session.require(Role::Operator)?;
    let path = app.program_path(&name)?;
    let text = program_text(&app, &body)?;
    let config = Arc::clone(&app.config);
    let (text2, name2) = (text.to_string(), name.clone());
    let errors =
        tokio::task::spawn_blocking(move || crate::preview::check(&config, &name2, &text2))
            .await
            .map_err(|e| Problem::internal(e.to_string()))?;
    if !errors.is_empty() {
        return Err(Problem::unprocessable(
            "program.errors",
            format!("{} error(s) in the program", errors.len()),
        )
        .with_extra(serde_json::json!({ "errors": errors })));
    }
    crate::files::write_atomically(&path, text.as_bytes(), 0o644)
        .map_err(|e| Problem::internal(e.to_string()))?;
    Ok((
        StatusCode::CREATED,
        Json(ProgramInfo {
            name,
            size: body.len() as u64,
            lines: text.lines().count() as u64,
        }),
    )
        .into_response())
}

/// Checks a program text with the interpreter as an upload would, without storing it
/// (an editor checks as the operator types).
#[utoipa::path(post, path = "/api/programs/{name}/check", tag = "programs", security(("bearer" = [])),
    params(("name" = String, Path, description = "The name the text would have (errors name it)")),
    request_body(content = String, content_type = "text/plain"),
    responses((status = 200, body = ProgramCheck), (status = 413, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn check_program(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(name): Path<String>,
    body: Bytes,
) -> ApiResult<Json<ProgramCheck>> {
    caller.viewer()?;
    app.program_path(&name)?;
    let text = program_text(&app, &body)?.to_string();
    let config = Arc::clone(&app.config);
    let lines = text.lines().count() as u64;
    let errors = tokio::task::spawn_blocking(move || crate::preview::check(&config, &name, &text))
        .await
        .map_err(|e| Problem::internal(e.to_string()))?;
    Ok(Json(ProgramCheck { errors, lines }))
}

/// Deletes a program.
#[utoipa::path(delete, path = "/api/programs/{name}", tag = "programs", security(("bearer" = [])),
    params(("name" = String, Path, description = "File name")),
    responses((status = 204), (status = 404, body = Problem, content_type = "application/problem+json")))]
pub async fn delete_program(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(name): Path<String>,
) -> ApiResult<StatusCode> {
    caller.session.require(Role::Operator)?;
    let path = app.program_path(&name)?;
    std::fs::remove_file(&path)
        .map_err(|_| Problem::not_found("program.not_found", format!("no program {name}")))?;
    Ok(StatusCode::NO_CONTENT)
}

/// The query of the tool-path preview.
#[derive(Debug, Deserialize, IntoParams)]
pub struct PreviewFormat {
    /// `json` (default) or `binary`: one chain of points, f32 coordinates (the layout is in
    /// docs/hmi.md and `preview::encode_binary`), for programs of a million segments.
    #[serde(default)]
    format: Option<String>,
}

/// The tool path: the canonical motion as polylines (arcs within 0.01 mm).
#[utoipa::path(get, path = "/api/programs/{name}/preview", tag = "programs", security(("bearer" = [])),
    params(("name" = String, Path, description = "File name"), PreviewFormat),
    responses((status = 200, body = Preview),
        (status = 200, description = "`format=binary`: the chain of points (docs/hmi.md)", content_type = "application/octet-stream"),
        (status = 404, body = Problem, content_type = "application/problem+json")))]
pub async fn preview(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(name): Path<String>,
    Query(q): Query<PreviewFormat>,
) -> ApiResult<Response> {
    caller.viewer()?;
    let binary = match q.format.as_deref() {
        None | Some("json") => false,
        Some("binary") => true,
        Some(_) => {
            return Err(Problem::bad_request(
                "api.bad_query",
                "format is json or binary",
            ));
        }
    };
    let text = app.read_program(&name)?;
    let config = Arc::clone(&app.config);
    let r = tokio::task::spawn_blocking(move || {
        let p = crate::preview::preview(&config, &name, &text);
        if binary {
            (
                [(header::CONTENT_TYPE, "application/octet-stream")],
                crate::preview::encode_binary(&p),
            )
                .into_response()
        } else {
            Json(p).into_response()
        }
    })
    .await
    .map_err(|e| Problem::internal(e.to_string()))?;
    Ok(r)
}

/// The cycle time from the planner on this machine file in virtual time (what `rtcnc sim`
/// gives). One estimate runs at a time.
#[utoipa::path(get, path = "/api/programs/{name}/estimate", tag = "programs", security(("bearer" = [])),
    params(("name" = String, Path, description = "File name")),
    responses((status = 200, body = Estimate), (status = 404, body = Problem, content_type = "application/problem+json")))]
pub async fn estimate(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(name): Path<String>,
) -> ApiResult<Json<Estimate>> {
    caller.viewer()?;
    let path = app.program_path(&name)?;
    if !path.is_file() {
        return Err(Problem::not_found(
            "program.not_found",
            format!("no program {name}"),
        ));
    }
    let _one = app.estimating.lock().await;
    let config = Arc::clone(&app.config);
    let e = tokio::task::spawn_blocking(move || {
        crate::preview::estimate(&config, &path, Duration::from_secs(4 * 3600))
    })
    .await
    .map_err(|e| Problem::internal(e.to_string()))?
    .map_err(|e| Problem::unprocessable("program.estimate", e.to_string()))?;
    Ok(Json(e))
}

// ----- setup -----------------------------------------------------------------------------

/// The tool table.
#[utoipa::path(get, path = "/api/setup/tools", tag = "setup", security(("bearer" = [])),
    responses((status = 200, body = Vec<Tool>)))]
pub async fn tools(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Json<Vec<Tool>>> {
    caller.viewer()?;
    let path = app.tool_table_path()?;
    let table =
        rtcnc_gcode::ToolTable::load(&path).map_err(|e| Problem::internal(e.to_string()))?;
    Ok(Json(
        table
            .tools()
            .iter()
            .map(|t| crate::tool_model(t, &app.machine.meta()))
            .collect(),
    ))
}

/// Replaces the tool table: written atomically (write, fsync, rename), then the machine
/// reads it again (it must be idle).
#[utoipa::path(put, path = "/api/setup/tools", tag = "setup", security(("bearer" = [])),
    request_body = Vec<Tool>, responses((status = 200, body = Ack), (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json"), (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn set_tools(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(tools): Json<Vec<Tool>>,
) -> ApiResult<Response> {
    caller.session.require(Role::Setter)?;
    let path = app.tool_table_path()?;
    let table = crate::tool_table(&tools)?;
    let state = app.status_now().state;
    if !matches!(state.as_str(), "idle" | "estop" | "fault") {
        return Err(Problem::conflict(
            Refusal::Busy.code(),
            "the tool table changes only while the machine is idle",
        ));
    }
    app.machine.client()?;
    crate::files::write_atomically(&path, table.to_text().as_bytes(), 0o644)
        .map_err(|e| Problem::internal(e.to_string()))?;
    run_command(&app, wire(command::RELOAD_TOOL_TABLE)).await
}

/// The work offsets G54..G59.3 as persisted (the parameter file).
#[utoipa::path(get, path = "/api/setup/offsets", tag = "setup", security(("bearer" = [])),
    responses((status = 200, body = Vec<WorkOffset>)))]
pub async fn offsets(
    State(app): State<Arc<App>>,
    caller: Caller,
) -> ApiResult<Json<Vec<WorkOffset>>> {
    caller.viewer()?;
    Ok(Json(app.work_offsets()?))
}

/// Sets a work offset: an MDI `G10 L2 P.. ` line, which the machine persists atomically in
/// its parameter file (so the machine must be idle).
#[utoipa::path(put, path = "/api/setup/offsets/{system}", tag = "setup", security(("bearer" = [])),
    params(("system" = String, Path, description = "G54 .. G59.3")),
    request_body = WorkOffset, responses((status = 200, body = Ack), (status = 409, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn set_offset(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(system): Path<String>,
    Json(body): Json<WorkOffset>,
) -> ApiResult<Response> {
    caller.session.require(Role::Setter)?;
    let p = crate::work_system_number(&system)
        .ok_or_else(|| Problem::unprocessable("command.bad_value", "the system is G54 .. G59.3"))?;
    let meta = app.machine.meta();
    let mut line = format!("G10 L2 P{p}");
    for (letter, v) in &body.offset.0 {
        if meta.axis_index(letter).is_none() || !v.is_finite() {
            return Err(Problem::unprocessable(
                "command.bad_value",
                format!("axis {letter}: not on this machine or not a number"),
            ));
        }
        line.push_str(&format!(" {}{v}", letter.to_uppercase()));
    }
    if body.rotation != 0.0 && body.rotation.is_finite() {
        line.push_str(&format!(" R{}", body.rotation));
    }
    let serial = app.machine.send(mdi_wire(&line)?)?;
    finish(&app, serial, true).await
}

/// The machine file (TOML) and whether it changed since the API process started.
#[utoipa::path(get, path = "/api/setup/machine", tag = "setup", security(("bearer" = [])),
    responses((status = 200, body = MachineFile)))]
pub async fn machine_file(
    State(app): State<Arc<App>>,
    caller: Caller,
) -> ApiResult<Json<MachineFile>> {
    caller.viewer()?;
    let path = &app.options.config_path;
    let text = std::fs::read_to_string(path)
        .map_err(|e| Problem::internal(format!("{}: {e}", path.display())))?;
    Ok(Json(MachineFile {
        path: path.display().to_string(),
        changed_since_start: text != app.config_text_at_start,
        text,
        handwheel_units_per_count: app.config.handwheel.units_per_count,
    }))
}

/// Replaces the machine file (admin): checked as the machine checks it at its start (the
/// TOML, every value, the kernel built on it with its PLC program), written atomically,
/// taken by the machine process at its next start. Refused with the key and the reason.
#[utoipa::path(put, path = "/api/setup/machine", tag = "setup", security(("bearer" = [])),
    request_body(content = String, content_type = "text/plain"),
    responses((status = 200, body = MachineFileSaved), (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn set_machine_file(
    State(app): State<Arc<App>>,
    caller: Caller,
    body: Bytes,
) -> ApiResult<Json<MachineFileSaved>> {
    caller.session.require(Role::Admin)?;
    let text = std::str::from_utf8(&body)
        .map_err(|_| Problem::unprocessable("setup.machine_invalid", "not UTF-8 text"))?
        .to_string();
    let path = app.options.config_path.clone();
    let (path2, text2) = (path.clone(), text.clone());
    tokio::task::spawn_blocking(move || crate::machine_file::validate(&path2, &text2))
        .await
        .map_err(|e| Problem::internal(e.to_string()))?
        .map_err(|e| Problem::unprocessable("setup.machine_invalid", e))?;
    crate::files::write_atomically(&path, text.as_bytes(), 0o644)
        .map_err(|e| Problem::internal(e.to_string()))?;
    Ok(Json(MachineFileSaved {
        size: text.len() as u64,
        applies_at_next_start: true,
    }))
}

// ----- PLC -------------------------------------------------------------------------------

async fn plc_call(app: &App, kind: u32, path: &str, value: &str) -> ApiResult<String> {
    let r = app.machine.service(kind, path, value).await?;
    if r.ok == 1 {
        Ok(r.text.as_str().to_string())
    } else {
        let code = r.code.as_str();
        let status = if code == "plc.absent" || code == "plc.unknown-variable" {
            StatusCode::NOT_FOUND
        } else {
            StatusCode::UNPROCESSABLE_ENTITY
        };
        Err(Problem::new(status, code, r.text.as_str()))
    }
}

/// Every variable of the PLC program (compiled from the machine file's `[plc] program`).
#[utoipa::path(get, path = "/api/plc/variables", tag = "plc", security(("bearer" = [])),
    responses((status = 200, body = Vec<PlcVariableInfo>), (status = 404, body = Problem, content_type = "application/problem+json")))]
pub async fn plc_variables(
    State(app): State<Arc<App>>,
    caller: Caller,
) -> ApiResult<Json<Vec<PlcVariableInfo>>> {
    caller.viewer()?;
    let config = Arc::clone(&app.config);
    tokio::task::spawn_blocking(move || crate::machine_file::plc_variables(&config))
        .await
        .map_err(|e| Problem::internal(e.to_string()))?
        .map(Json)
        .map_err(|e| Problem::not_found("plc.absent", e))
}

/// Reads a PLC variable.
#[utoipa::path(get, path = "/api/plc/variables/{path}", tag = "plc", security(("bearer" = [])),
    params(("path" = String, Path, description = "Variable path")),
    responses((status = 200, body = PlcVariable), (status = 404, body = Problem, content_type = "application/problem+json")))]
pub async fn plc_read(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(path): Path<String>,
) -> ApiResult<Json<PlcVariable>> {
    caller.viewer()?;
    let value = plc_call(&app, service::PLC_READ, &path, "").await?;
    Ok(Json(PlcVariable { path, value }))
}

/// Sets the PLC watch list; the values come in the status (`plc_watch`) every period.
#[utoipa::path(put, path = "/api/plc/watch", tag = "plc", security(("bearer" = [])),
    request_body = PlcWatch, responses((status = 204), (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn plc_watch(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<PlcWatch>,
) -> ApiResult<StatusCode> {
    caller.session.require(Role::Operator)?;
    plc_call(&app, service::PLC_WATCH, &b.paths.join(","), "").await?;
    app.machine.set_watch_paths(b.paths);
    Ok(StatusCode::NO_CONTENT)
}

/// Forces a PLC variable (setter).
#[utoipa::path(post, path = "/api/plc/force", tag = "plc", security(("bearer" = [])),
    request_body = PlcForce, responses((status = 200, body = PlcVariable), (status = 403, body = Problem, content_type = "application/problem+json"),
        (status = 422, body = Problem, content_type = "application/problem+json")))]
pub async fn plc_force(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<PlcForce>,
) -> ApiResult<Json<PlcVariable>> {
    caller.session.require(Role::Setter)?;
    let value = plc_call(&app, service::PLC_FORCE, &b.path, &b.value).await?;
    Ok(Json(PlcVariable {
        path: b.path,
        value,
    }))
}

/// Releases a PLC force (setter).
#[utoipa::path(delete, path = "/api/plc/force/{path}", tag = "plc", security(("bearer" = [])),
    params(("path" = String, Path, description = "Variable path")),
    responses((status = 204), (status = 403, body = Problem, content_type = "application/problem+json")))]
pub async fn plc_unforce(
    State(app): State<Arc<App>>,
    caller: Caller,
    Path(path): Path<String>,
) -> ApiResult<StatusCode> {
    caller.session.require(Role::Setter)?;
    plc_call(&app, service::PLC_UNFORCE, &path, "").await?;
    Ok(StatusCode::NO_CONTENT)
}

// ----- diagnostics -----------------------------------------------------------------------

/// The fault history (since the API started).
#[utoipa::path(get, path = "/api/faults", tag = "diagnostics", security(("bearer" = [])),
    responses((status = 200, body = Vec<FaultRecord>)))]
pub async fn faults(
    State(app): State<Arc<App>>,
    caller: Caller,
) -> ApiResult<Json<Vec<FaultRecord>>> {
    caller.viewer()?;
    Ok(Json(app.machine.faults()))
}

/// Acknowledges the faults up to a sequence number (operator).
#[utoipa::path(post, path = "/api/faults/acknowledge", tag = "diagnostics", security(("bearer" = [])),
    request_body = FaultAck, responses((status = 200, body = Vec<FaultRecord>)))]
pub async fn acknowledge_faults(
    State(app): State<Arc<App>>,
    caller: Caller,
    Json(b): Json<FaultAck>,
) -> ApiResult<Json<Vec<FaultRecord>>> {
    caller.session.require(Role::Operator)?;
    app.machine.acknowledge_faults(b.up_to_seq);
    Ok(Json(app.machine.faults()))
}

/// Task timing from the executive's monitor.
#[utoipa::path(get, path = "/api/diagnostics/timing", tag = "diagnostics", security(("bearer" = [])),
    responses((status = 200, body = Timing), (status = 503, body = Problem, content_type = "application/problem+json")))]
pub async fn timing(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Json<Timing>> {
    caller.viewer()?;
    let t = app.machine.client()?.timing();
    let us = |ns: u64| ns as f64 / 1e3;
    Ok(Json(Timing {
        fifo: t.fifo != 0,
        underruns: t.underruns,
        tasks: t.tasks[..(t.count as usize).min(t.tasks.len())]
            .iter()
            .map(|x| TaskTiming {
                name: rtcnc_kernel::link::layout::field_name(&x.name).to_string(),
                activations: x.activations,
                execution_mean_us: us(x.execution_mean_ns),
                execution_p99_us: us(x.execution_p99_ns),
                execution_max_us: us(x.execution_max_ns),
                lateness_p99_us: us(x.lateness_p99_ns),
                lateness_max_us: us(x.lateness_max_ns),
                deadline_misses: x.deadline_misses,
                skipped_releases: x.skipped_releases,
            })
            .collect(),
    }))
}

/// The last ten seconds of set-points, feedback and following errors per joint, as Chrome
/// trace-event JSON (counter tracks; Perfetto opens it).
#[utoipa::path(get, path = "/api/diagnostics/trace", tag = "diagnostics", security(("bearer" = [])),
    responses((status = 200, description = "Chrome trace-event JSON", content_type = "application/json")))]
pub async fn trace(State(app): State<Arc<App>>, caller: Caller) -> ApiResult<Response> {
    caller.viewer()?;
    let meta = app.machine.meta();
    let samples = app.machine.trace();
    let mut out = String::with_capacity(samples.len() * 200 + 64);
    out.push_str("{\"displayTimeUnit\":\"ms\",\"traceEvents\":[");
    let mut first = true;
    for s in &samples {
        let ts = s.time_ns as f64 / 1e3;
        for (j, name) in meta.joints.iter().enumerate().take(s.joints as usize) {
            if !first {
                out.push(',');
            }
            first = false;
            out.push_str(&format!(
                "{{\"name\":\"joint {}\",\"ph\":\"C\",\"ts\":{ts:.3},\"pid\":1,\"tid\":1,\"args\":{{\"setpoint\":{},\"feedback\":{},\"following_error\":{}}}}}",
                crate::json_escape(name), s.setpoint[j], s.feedback[j], s.following_error[j]
            ));
        }
        out.push_str(&format!(
            ",{{\"name\":\"path speed\",\"ph\":\"C\",\"ts\":{ts:.3},\"pid\":1,\"tid\":1,\"args\":{{\"speed\":{},\"line\":{}}}}}",
            s.path_speed, s.line
        ));
    }
    out.push_str("]}");
    Ok(([(header::CONTENT_TYPE, "application/json")], out).into_response())
}
