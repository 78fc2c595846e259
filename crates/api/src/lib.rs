//! `rtcnc-api`: the API server (layer 4). REST and one WebSocket over the machine's
//! shared-memory link (`rtcnc_kernel::link`), with users and roles, one control lease, and
//! an OpenAPI 3.1 document generated from this code. docs/api.md describes it.
// A handler's error is its HTTP answer (a problem document), made once per failed request:
// boxing it would buy nothing.
#![allow(clippy::result_large_err)]
// Axis-indexed arrays read best with the axis index.
#![allow(clippy::needless_range_loop)]

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::routing::{get, post, put};
use rtcnc_kernel::MachineConfig;
use utoipa::OpenApi;

pub mod auth;
pub mod files;
pub mod hmi;
pub mod machine;
pub mod machine_file;
pub mod models;
pub mod preview;
pub mod problem;
pub mod routes;
pub mod tls;
pub mod ws;

use machine::MachineConn;
use problem::Problem;

/// Largest JSON body, bytes.
pub const MAX_JSON_BODY: usize = 64 * 1024;
/// Largest machine file written over the API, bytes.
pub const MAX_MACHINE_FILE: usize = 1 << 20;
/// Largest WebSocket message from a client, bytes.
pub const MAX_WS_MESSAGE: usize = 4096;

/// How the API server runs.
#[derive(Debug, Clone)]
pub struct ApiOptions {
    /// The machine file (for the preview, the estimate, the setup files).
    pub config_path: PathBuf,
    /// The machine's segment name.
    pub segment: String,
    /// Address to listen on.
    pub listen: SocketAddr,
    /// TLS certificate and key (PEM).
    pub tls: Option<(PathBuf, PathBuf)>,
    /// Plain HTTP on an address other than loopback, knowingly.
    pub insecure_http: bool,
    /// The users file.
    pub users_file: PathBuf,
    /// The program store.
    pub programs_dir: PathBuf,
    /// Session lifetime.
    pub session_ttl: Duration,
    /// Largest program upload, bytes.
    pub max_upload_bytes: usize,
}

/// What every handler shares.
pub struct App {
    /// Options.
    pub options: ApiOptions,
    /// The machine file.
    pub config: Arc<MachineConfig>,
    /// The machine.
    pub machine: Arc<MachineConn>,
    /// Users, sessions, lease.
    pub auth: auth::Auth,
    /// One estimate at a time.
    pub estimating: tokio::sync::Mutex<()>,
    /// The machine file's text when this process started (what the machine runs, unless
    /// it was restarted since).
    pub config_text_at_start: String,
}

/// The OpenAPI document.
#[derive(OpenApi)]
#[openapi(
    info(title = "rtcnc API", description = "REST and WebSocket API of an rtcnc machine: status, events, programs, control, setup, PLC variables, diagnostics. Errors are RFC 9457 problem documents with a stable code. See docs/api.md."),
    paths(
        routes::login, routes::session_info, routes::logout, routes::change_password,
        routes::lease, routes::acquire_lease, routes::release_lease,
        routes::info, routes::status, routes::events, ws::ws, routes::command_ack,
        routes::reset, routes::estop, routes::feed_hold, routes::resume, routes::stop,
        routes::load_program, routes::cycle_start, routes::single_block, routes::optional_stop,
        routes::block_delete, routes::mdi, routes::jog, routes::jog_keep_alive, routes::jog_stop,
        routes::home, routes::home_axis, routes::mode, routes::handwheel, routes::overrides, routes::spindle, routes::coolant,
        routes::list_programs, routes::read_program, routes::upload_program, routes::delete_program,
        routes::check_program, routes::preview, routes::estimate,
        routes::tools, routes::set_tools, routes::offsets, routes::set_offset,
        routes::machine_file, routes::set_machine_file,
        routes::plc_variables, routes::plc_read, routes::plc_watch, routes::plc_force, routes::plc_unforce,
        routes::faults, routes::acknowledge_faults, routes::timing, routes::trace,
    ),
    components(schemas(problem::Problem)),
    modifiers(&BearerAuth),
    tags(
        (name = "session", description = "Log-in, sessions, the control lease"),
        (name = "status", description = "Status snapshot, events, the WebSocket"),
        (name = "control", description = "Commands (operator with the lease; e-stop and feed hold: any operator)"),
        (name = "programs", description = "The program store, preview, cycle-time estimate"),
        (name = "setup", description = "Tool table and work offsets (setter writes), the machine file (admin writes)"),
        (name = "plc", description = "PLC variables"),
        (name = "diagnostics", description = "Faults, task timing, trace"),
    )
)]
pub struct ApiDoc;

struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, doc: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
        let components = doc.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
    }
}

/// The OpenAPI document as pretty JSON (what `docs/openapi.json` holds).
pub fn openapi_json() -> String {
    let mut doc = ApiDoc::openapi();
    doc.info.version = env!("CARGO_PKG_VERSION").to_string();
    doc.to_pretty_json().unwrap_or_default() + "\n"
}

/// The router.
pub fn router(app: Arc<App>) -> Router {
    use routes as r;
    let upload = DefaultBodyLimit::max(app.options.max_upload_bytes + 1);
    Router::new()
        .route(
            "/api/openapi.json",
            get(|| async {
                (
                    [(axum::http::header::CONTENT_TYPE, "application/json")],
                    openapi_json(),
                )
            }),
        )
        .route("/api", get(r::info))
        .route(
            "/api/session",
            post(r::login).get(r::session_info).delete(r::logout),
        )
        .route("/api/session/password", post(r::change_password))
        .route(
            "/api/lease",
            get(r::lease)
                .post(r::acquire_lease)
                .delete(r::release_lease),
        )
        .route("/api/status", get(r::status))
        .route("/api/events", get(r::events))
        .route("/api/ws", get(ws::ws))
        .route("/api/commands/{serial}", get(r::command_ack))
        .route("/api/control/reset", post(r::reset))
        .route("/api/control/estop", post(r::estop))
        .route("/api/control/feed-hold", post(r::feed_hold))
        .route("/api/control/resume", post(r::resume))
        .route("/api/control/stop", post(r::stop))
        .route("/api/control/program", post(r::load_program))
        .route("/api/control/cycle-start", post(r::cycle_start))
        .route("/api/control/single-block", post(r::single_block))
        .route("/api/control/optional-stop", post(r::optional_stop))
        .route("/api/control/block-delete", post(r::block_delete))
        .route("/api/control/mdi", post(r::mdi))
        .route("/api/control/jog", post(r::jog))
        .route("/api/control/jog/keep-alive", post(r::jog_keep_alive))
        .route("/api/control/jog/stop", post(r::jog_stop))
        .route("/api/control/home", post(r::home))
        .route("/api/control/home/{axis}", post(r::home_axis))
        .route("/api/control/mode", post(r::mode))
        .route("/api/control/handwheel", post(r::handwheel))
        .route("/api/control/overrides", post(r::overrides))
        .route("/api/control/spindle", post(r::spindle))
        .route("/api/control/coolant", post(r::coolant))
        .route("/api/programs", get(r::list_programs))
        .route(
            "/api/programs/{name}",
            get(r::read_program)
                .put(r::upload_program)
                .delete(r::delete_program)
                .layer(upload),
        )
        .route(
            "/api/programs/{name}/check",
            post(r::check_program).layer(DefaultBodyLimit::max(app.options.max_upload_bytes + 1)),
        )
        .route("/api/programs/{name}/preview", get(r::preview))
        .route("/api/programs/{name}/estimate", get(r::estimate))
        .route("/api/setup/tools", get(r::tools).put(r::set_tools))
        .route("/api/setup/offsets", get(r::offsets))
        .route("/api/setup/offsets/{system}", put(r::set_offset))
        .route(
            "/api/setup/machine",
            get(r::machine_file)
                .put(r::set_machine_file)
                .layer(DefaultBodyLimit::max(MAX_MACHINE_FILE)),
        )
        .route("/api/plc/variables", get(r::plc_variables))
        .route("/api/plc/variables/{path}", get(r::plc_read))
        .route("/api/plc/watch", put(r::plc_watch))
        .route("/api/plc/force", post(r::plc_force))
        .route(
            "/api/plc/force/{path}",
            axum::routing::delete(r::plc_unforce),
        )
        .route("/api/faults", get(r::faults))
        .route("/api/faults/acknowledge", post(r::acknowledge_faults))
        .route("/api/diagnostics/timing", get(r::timing))
        .route("/api/diagnostics/trace", get(r::trace))
        .route(
            "/api/{*rest}",
            axum::routing::any(|| async {
                Problem::not_found("api.not_found", "no such endpoint")
            }),
        )
        .fallback(hmi::serve)
        .layer(DefaultBodyLimit::max(MAX_JSON_BODY))
        .layer(axum::middleware::from_fn_with_state(
            Arc::clone(&app),
            read_body_first,
        ))
        .layer(axum::middleware::map_response(problem::as_problem))
        .with_state(app)
}

/// Reads the whole request body (within its limit) before the handler runs: a handler that
/// answers without reading it (a 401, 403 or 409 before the body matters) would otherwise
/// make the server close the connection, and a client that reuses it finds it gone.
async fn read_body_first(
    axum::extract::State(app): axum::extract::State<Arc<App>>,
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> axum::response::Response {
    use axum::response::IntoResponse as _;
    let limit = if request.uri().path().starts_with("/api/programs/") {
        app.options.max_upload_bytes
    } else if request.uri().path() == "/api/setup/machine" {
        MAX_MACHINE_FILE
    } else {
        MAX_JSON_BODY
    };
    let (parts, body) = request.into_parts();
    match axum::body::to_bytes(body, limit + 1).await {
        Ok(bytes) => {
            let request = axum::extract::Request::from_parts(parts, axum::body::Body::from(bytes));
            next.run(request).await
        }
        Err(_) => Problem::new(
            axum::http::StatusCode::PAYLOAD_TOO_LARGE,
            "api.too_large",
            format!("the request body is larger than {limit} bytes"),
        )
        .into_response(),
    }
}

impl App {
    /// The status document with the lease holder.
    pub fn status_now(&self) -> models::Status {
        let mut s = (*self.machine.status()).clone();
        s.lease_holder = self.auth.lease().map(|l| l.user);
        s
    }

    /// The file of a program name, or 400 for a bad name.
    pub fn program_path(&self, name: &str) -> Result<PathBuf, Problem> {
        if !valid_program_name(name) {
            return Err(Problem::bad_request(
                "program.bad_name",
                "a program name has letters, digits, '.', '_' and '-' (at most 64), not starting with '.'",
            ));
        }
        Ok(self.options.programs_dir.join(name))
    }

    /// A program's text.
    pub fn read_program(&self, name: &str) -> Result<String, Problem> {
        let path = self.program_path(name)?;
        std::fs::read_to_string(&path)
            .map_err(|_| Problem::not_found("program.not_found", format!("no program {name}")))
    }

    /// The tool table file.
    pub fn tool_table_path(&self) -> Result<PathBuf, Problem> {
        self.config
            .files
            .tool_table
            .as_ref()
            .map(|p| self.config.resolve(p))
            .ok_or_else(|| {
                Problem::not_found(
                    "setup.no_tool_table",
                    "the machine file names no tool table ([files] tool_table)",
                )
            })
    }

    /// The work offsets in the parameter file.
    pub fn work_offsets(&self) -> Result<Vec<models::WorkOffset>, Problem> {
        let params = match &self.config.files.parameters {
            Some(p) => {
                let path = self.config.resolve(p);
                if path.exists() {
                    rtcnc_gcode::Parameters::load(&path)
                        .map_err(|e| Problem::internal(e.to_string()))?
                } else {
                    rtcnc_gcode::Parameters::new()
                }
            }
            None => rtcnc_gcode::Parameters::new(),
        };
        let meta = self.machine.meta();
        let names = [
            "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
        ];
        Ok(names
            .iter()
            .enumerate()
            .map(|(n, name)| {
                let base = 5221 + 20 * n;
                models::WorkOffset {
                    system: name.to_string(),
                    offset: (0..9)
                        .filter(|i| meta.axes_present & (1 << i) != 0)
                        .map(|i| (machine::AXIS_LETTERS[i].to_string(), params.get(base + i)))
                        .collect(),
                    rotation: params.get(base + 9),
                }
            })
            .collect())
    }
}

/// Program names: letters, digits, `.`, `_`, `-`, at most 64, not starting with a dot.
pub fn valid_program_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 64
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b))
}

/// `G54`..`G59.3` as 1..9.
pub fn work_system_number(name: &str) -> Option<u32> {
    let names = [
        "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
    ];
    names
        .iter()
        .position(|n| n.eq_ignore_ascii_case(name))
        .map(|i| i as u32 + 1)
}

/// The API's document of a tool.
pub fn tool_model(t: &rtcnc_gcode::Tool, meta: &machine::Meta) -> models::Tool {
    let o = t.offset.to_array();
    models::Tool {
        number: t.number,
        pocket: t.pocket,
        offset: (0..9)
            .filter(|&i| meta.axes_present & (1 << i) != 0 || o[i] != 0.0)
            .map(|i| (machine::AXIS_LETTERS[i].to_string(), o[i]))
            .collect(),
        diameter: t.diameter,
        front_angle: t.front_angle,
        back_angle: t.back_angle,
        orientation: t.orientation,
        comment: t.comment.clone(),
    }
}

/// A tool table from the API's documents (checked).
pub fn tool_table(tools: &[models::Tool]) -> Result<rtcnc_gcode::ToolTable, Problem> {
    let mut table = rtcnc_gcode::ToolTable::new();
    let mut seen = std::collections::BTreeSet::new();
    for t in tools {
        if t.number < 0 || t.pocket < 0 || !seen.insert(t.number) {
            return Err(Problem::unprocessable(
                "setup.bad_tool",
                format!(
                    "tool {}: numbers and pockets are >= 0 and numbers unique",
                    t.number
                ),
            ));
        }
        let mut tool = rtcnc_gcode::Tool::new(t.number, t.pocket);
        let mut o = [0.0; 9];
        for (letter, v) in &t.offset.0 {
            let i = machine::AXIS_LETTERS
                .iter()
                .position(|l| l.eq_ignore_ascii_case(letter))
                .ok_or_else(|| {
                    Problem::unprocessable("setup.bad_tool", format!("no axis {letter}"))
                })?;
            o[i] = *v;
        }
        let numbers = o
            .iter()
            .chain([&t.diameter, &t.front_angle, &t.back_angle])
            .all(|v| v.is_finite());
        if !numbers {
            return Err(Problem::unprocessable(
                "setup.bad_tool",
                format!("tool {}: a value is not a number", t.number),
            ));
        }
        tool.offset = rtcnc_gcode::Pose::from_array(o);
        tool.diameter = t.diameter;
        tool.front_angle = t.front_angle;
        tool.back_angle = t.back_angle;
        tool.orientation = t.orientation;
        // One line per tool: no line breaks (nor a second ';') in the comment.
        tool.comment = t.comment.replace(['\n', '\r', ';'], " ");
        table.set(tool);
    }
    Ok(table)
}

/// A string as the inside of a JSON string literal.
pub fn json_escape(s: &str) -> String {
    let quoted = serde_json::to_string(s).unwrap_or_default();
    quoted[1..quoted.len().saturating_sub(1).max(1)].to_string()
}

/// A continuous jog's keep-alive from the WebSocket.
pub fn ws_keep_alive(app: &App, caller: &routes::Caller, axis: &str) -> Result<(), Problem> {
    app.auth.require_lease(&caller.session)?;
    let axis = app.machine.meta().axis_index(axis).ok_or_else(|| {
        Problem::unprocessable(
            "command.bad_axis",
            format!("no axis {axis} on this machine"),
        )
    })?;
    let mut w = rtcnc_kernel::link::layout::WireCommand {
        kind: rtcnc_kernel::link::layout::command::JOG_KEEP_ALIVE,
        ..Default::default()
    };
    w.axis = axis;
    app.machine.send(w).map(|_| ())
}

/// Runs the API server until SIGINT or SIGTERM.
pub fn run(options: ApiOptions) -> anyhow::Result<()> {
    run_with(options, |_| Ok(()))
}

/// Runs the API server until SIGINT or SIGTERM, with more surfaces of the same process
/// (OPC UA, MQTT): `surfaces` is called inside the server's Tokio runtime before it listens,
/// to spawn their tasks over the same machine connection.
pub fn run_with(
    options: ApiOptions,
    surfaces: impl FnOnce(Arc<App>) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let config = MachineConfig::load(&options.config_path).map_err(|e| {
        anyhow::anyhow!(
            "machine configuration {}: {e}",
            options.config_path.display()
        )
    })?;
    let loopback = options.listen.ip().is_loopback();
    if !loopback && options.tls.is_none() && !options.insecure_http {
        anyhow::bail!(
            "{} is not a loopback address: give --tls-cert and --tls-key (or [hmi] tls_certificate \
             and tls_key), or --insecure-http to serve plain HTTP knowingly",
            options.listen
        );
    }
    std::fs::create_dir_all(&options.programs_dir)
        .map_err(|e| anyhow::anyhow!("{}: {e}", options.programs_dir.display()))?;
    // What writers killed mid-write (kill -9, power loss) left beside the files.
    files::remove_stale_temporaries(&options.users_file);
    if let Some(t) = &config.files.tool_table {
        files::remove_stale_temporaries(&config.resolve(t));
    }
    let (auth, first_password) = auth::Auth::open(&options.users_file, options.session_ttl)?;
    if let Some(password) = first_password {
        // Printed once, to the terminal that started the server; never logged elsewhere.
        eprintln!(
            "rtcnc api: created {} with the user 'admin'; its one-time password is: {password}\n\
             rtcnc api: log in and change it (POST /api/session/password)",
            options.users_file.display()
        );
    }
    let config_text_at_start = std::fs::read_to_string(&options.config_path).unwrap_or_default();
    let machine = MachineConn::new(&options.segment, &config.machine.name);
    let link_thread = machine.start();
    let app = Arc::new(App {
        options: options.clone(),
        config: Arc::new(config),
        machine: Arc::clone(&machine),
        auth,
        estimating: tokio::sync::Mutex::new(()),
        config_text_at_start,
    });
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let result = runtime.block_on(async move {
        surfaces(Arc::clone(&app))?;
        let service = router(Arc::clone(&app)).into_make_service_with_connect_info::<ClientAddr>();
        let tcp = tokio::net::TcpListener::bind(options.listen)
            .await
            .map_err(|e| anyhow::anyhow!("listening on {}: {e}", options.listen))?;
        let local = tcp.local_addr()?;
        match &options.tls {
            Some((cert, key)) => {
                let tls = tls::server_config(cert, key)?;
                println!("rtcnc api: listening on https://{local}");
                let listener = tls::TlsListener::new(tcp, tls)?;
                axum::serve(listener, service)
                    .with_graceful_shutdown(shutdown())
                    .await?;
            }
            None => {
                println!("rtcnc api: listening on http://{local}");
                axum::serve(tcp, service)
                    .with_graceful_shutdown(shutdown())
                    .await?;
            }
        }
        anyhow::Ok(())
    });
    machine.shutdown();
    let _ = link_thread.join();
    result
}

/// The peer's address, for the log-in rate limit (over TCP or TLS).
#[derive(Debug, Clone, Copy)]
pub struct ClientAddr(pub SocketAddr);

impl
    axum::extract::connect_info::Connected<axum::serve::IncomingStream<'_, tokio::net::TcpListener>>
    for ClientAddr
{
    fn connect_info(stream: axum::serve::IncomingStream<'_, tokio::net::TcpListener>) -> Self {
        ClientAddr(*stream.remote_addr())
    }
}

impl axum::extract::connect_info::Connected<axum::serve::IncomingStream<'_, tls::TlsListener>>
    for ClientAddr
{
    fn connect_info(stream: axum::serve::IncomingStream<'_, tls::TlsListener>) -> Self {
        ClientAddr(*stream.remote_addr())
    }
}

async fn shutdown() {
    use tokio::signal::unix::{SignalKind, signal};
    let (Ok(mut term), Ok(mut int)) = (
        signal(SignalKind::terminate()),
        signal(SignalKind::interrupt()),
    ) else {
        return std::future::pending().await;
    };
    tokio::select! {
        _ = term.recv() => {}
        _ = int.recv() => {}
    }
}

/// The default users file of a machine file: `[hmi] users`, else `users.toml` beside it.
pub fn default_users_file(config: &MachineConfig, config_path: &Path) -> PathBuf {
    match &config.hmi.users {
        Some(p) => config.resolve(p),
        None => config_path
            .parent()
            .unwrap_or(Path::new("."))
            .join("users.toml"),
    }
}
