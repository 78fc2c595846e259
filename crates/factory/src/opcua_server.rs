//! The OPC UA server: the CNC companion model (OPC 40502) of this machine, its values from
//! the API's status documents, faults as `CncAlarmType` and operator messages as
//! `CncMessageType` events, log-in with the API's users.

use std::collections::{HashMap, HashSet};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use opcua::core_namespace::events::DiscreteAlarmType;
use opcua::crypto::SecurityPolicy;
use opcua::nodes::{AccessLevel, BaseEventType, EventNotifier};
use opcua::server::address_space::{AddressSpace, ObjectBuilder, VariableBuilder};
use opcua::server::authenticator::{AuthManager, Password, UserToken};
use opcua::server::node_manager::memory::simple_node_manager_imports;
use opcua::server::{ServerBuilder, ServerEndpoint, ServerHandle};
use opcua::types::{
    ByteString, DataTypeId, DataValue, DateTime, EUInformation, ExtensionObject, LocalizedText,
    MessageSecurityMode, NodeId, ObjectId, ObjectTypeId, QualifiedName, Range, StatusCode,
    UAString, UserTokenPolicy, UserTokenType, VariableTypeId, Variant,
};
use rtcnc_api::App;
use rtcnc_api::models::{Event, Status};
use tokio::sync::broadcast::error::RecvError;

use crate::cnc::{self, Unit};
use crate::config::{OpcUaSection, slug};
use crate::nodeset::{CNC_NAMESPACE, CncTypes};
use crate::sampling::{Clock, MachineNodeManager, Sampling, machine_node_manager};
use crate::trace::{Source, TraceFeed, TraceNodes};

/// Node manager of this machine's instance nodes.
const MACHINE_MANAGER: &str = "rtcnc machine";

/// A fault as OPC 40502's `CncAlarmType` (a `DiscreteAlarmType`).
#[derive(Debug, opcua::Event)]
#[opcua(identifier = "i=1006", namespace = "http://opcfoundation.org/UA/CNC")]
pub(crate) struct CncAlarmEvent {
    /// The alarm's base.
    pub base: DiscreteAlarmType,
    /// Index of the CNC namespace.
    pub own_namespace_index: u16,
    /// rtcnc's fault code (`kernel.following_error`).
    pub alarm_identifier: UAString,
    /// Program line and joint, when the fault has them.
    pub aux_parameters: UAString,
    /// Where to read about it.
    pub help_source: UAString,
}

/// An operator message as OPC 40502's `CncMessageType`.
#[derive(Debug, opcua::Event)]
#[opcua(identifier = "i=1011", namespace = "http://opcfoundation.org/UA/CNC")]
pub(crate) struct CncMessageEvent {
    /// The event's base.
    pub base: BaseEventType,
    /// Index of the CNC namespace.
    pub own_namespace_index: u16,
}

/// Log-in with the API's users file: any user with a role reads; nothing is writable.
struct UsersAuth {
    app: Arc<App>,
    anonymous: bool,
}

#[async_trait::async_trait]
impl AuthManager for UsersAuth {
    async fn authenticate_anonymous_token(
        &self,
        _endpoint: &ServerEndpoint,
    ) -> Result<(), opcua::types::Error> {
        if self.anonymous {
            Ok(())
        } else {
            Err(opcua::types::Error::new(
                StatusCode::BadIdentityTokenRejected,
                "anonymous sessions are off ([opcua] anonymous)",
            ))
        }
    }

    async fn authenticate_username_identity_token(
        &self,
        _endpoint: &ServerEndpoint,
        username: &str,
        password: &Password,
    ) -> Result<UserToken, opcua::types::Error> {
        let app = Arc::clone(&self.app);
        let (user, password) = (username.to_string(), password.get().to_string());
        // argon2 takes tens of milliseconds by design: not on the server's workers.
        let found = tokio::task::spawn_blocking(move || app.auth.verify_password(&user, &password))
            .await
            .ok()
            .flatten();
        match found {
            Some(u) if !u.must_change => Ok(UserToken(u.name)),
            Some(_) => Err(opcua::types::Error::new(
                StatusCode::BadIdentityTokenRejected,
                "the one-time password must be changed first (over the API)",
            )),
            None => Err(opcua::types::Error::new(
                StatusCode::BadUserAccessDenied,
                "wrong user name or password",
            )),
        }
    }

    fn user_token_policies(&self, endpoint: &ServerEndpoint) -> Vec<UserTokenPolicy> {
        let mut policies = Vec::new();
        if self.anonymous {
            policies.push(UserTokenPolicy {
                policy_id: "anonymous".into(),
                token_type: UserTokenType::Anonymous,
                issued_token_type: UAString::null(),
                issuer_endpoint_url: UAString::null(),
                security_policy_uri: UAString::null(),
            });
        }
        policies.push(UserTokenPolicy {
            policy_id: opcua::server::authenticator::user_pass_security_policy_id(endpoint),
            token_type: UserTokenType::UserName,
            issued_token_type: UAString::null(),
            issuer_endpoint_url: UAString::null(),
            // On an unsecured endpoint the password is still encrypted, with the server's
            // certificate (Basic256Sha256's asymmetric algorithm).
            security_policy_uri: if endpoint.security_policy() == SecurityPolicy::None {
                UAString::from(SecurityPolicy::Basic256Sha256.to_uri())
            } else {
                UAString::null()
            },
        });
        policies
    }
}

/// A value the model serves: a value, or a status saying that rtcnc has no source for it
/// (a mandatory variable of the model the machine cannot measure, e.g. drive torque).
#[derive(Debug, Clone, PartialEq)]
enum Value {
    Good(Variant),
    Absent,
}

/// The instance nodes of one machine and where their values come from.
struct Model {
    ns: u16,
    cnc: u16,
    interface: NodeId,
    channel: NodeId,
    /// Axis letter, node, its joints' indices, rotational.
    axes: Vec<(String, NodeId, Vec<usize>, bool)>,
    spindle: Option<NodeId>,
    /// The drives are the simulated machine's, not physical ones.
    simulated: bool,
}

impl Model {
    fn id(&self, path: &str) -> NodeId {
        NodeId::new(self.ns, path.to_string())
    }
}

fn eu(unit: Unit) -> Variant {
    Variant::from(ExtensionObject::from_message(EUInformation {
        namespace_uri: "http://www.opcfoundation.org/UA/units/un/cefact".into(),
        unit_id: unit.unit_id(),
        display_name: LocalizedText::new("", unit.display),
        description: LocalizedText::new("en", unit.description),
    }))
}

struct NodeAdder<'a> {
    space: &'a mut AddressSpace,
    ns: u16,
    cnc: u16,
}

impl NodeAdder<'_> {
    fn object(&mut self, id: &NodeId, name: &str, type_id: NodeId, parent: &NodeId) {
        ObjectBuilder::new(id, QualifiedName::new(self.cnc, name), name)
            .has_type_definition(type_id)
            .component_of(parent.clone())
            .insert(self.space);
    }

    /// A variable of the model (BaseDataVariable, or AnalogUnit with its unit and range).
    fn variable(
        &mut self,
        parent: &NodeId,
        name: &str,
        data_type: impl Into<NodeId>,
        unit: Option<Unit>,
    ) -> NodeId {
        let id = NodeId::new(self.ns, format!("{}.{name}", path_of(parent)));
        let type_def: NodeId = if unit.is_some() {
            VariableTypeId::AnalogUnitType.into()
        } else {
            VariableTypeId::BaseDataVariableType.into()
        };
        VariableBuilder::new(&id, QualifiedName::new(self.cnc, name), name)
            .data_type(data_type)
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .has_type_definition(type_def)
            .component_of(parent.clone())
            .insert(self.space);
        if let Some(unit) = unit {
            self.property(
                &id,
                0,
                "EngineeringUnits",
                DataTypeId::EUInformation,
                eu(unit),
            );
            self.property(
                &id,
                0,
                "EURange",
                DataTypeId::Range,
                Variant::from(ExtensionObject::from_message(Range {
                    low: f64::MIN,
                    high: f64::MAX,
                })),
            );
        }
        id
    }

    fn array_variable(&mut self, parent: &NodeId, name: &str, data_type: DataTypeId) -> NodeId {
        let id = self.variable(parent, name, data_type, None);
        if let Some(opcua::nodes::NodeType::Variable(v)) = self.space.find_mut(&id) {
            v.set_value_rank(1);
        }
        id
    }

    fn property(
        &mut self,
        parent: &NodeId,
        ns: u16,
        name: &str,
        data_type: impl Into<NodeId>,
        value: Variant,
    ) {
        let id = NodeId::new(self.ns, format!("{}.{name}", path_of(parent)));
        VariableBuilder::new(&id, QualifiedName::new(ns, name), name)
            .data_type(data_type)
            .value(value)
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .has_type_definition(VariableTypeId::PropertyType)
            .property_of(parent.clone())
            .insert(self.space);
    }

    /// A `CncPositionVariableType` with ActPos, CmdPos, RemDist.
    fn position(&mut self, parent: &NodeId, name: &str, unit: Unit) -> NodeId {
        let id = NodeId::new(self.ns, format!("{}.{name}", path_of(parent)));
        VariableBuilder::new(&id, QualifiedName::new(self.cnc, name), name)
            .data_type(NodeId::new(self.cnc, 3007u32))
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .has_type_definition(NodeId::new(self.cnc, 2001u32))
            .component_of(parent.clone())
            .insert(self.space);
        for member in ["ActPos", "CmdPos", "RemDist"] {
            let m = NodeId::new(self.ns, format!("{}.{name}.{member}", path_of(parent)));
            VariableBuilder::new(&m, QualifiedName::new(self.cnc, member), member)
                .data_type(DataTypeId::Double)
                .access_level(AccessLevel::CURRENT_READ)
                .user_access_level(AccessLevel::CURRENT_READ)
                .has_type_definition(VariableTypeId::BaseDataVariableType)
                .component_of(id.clone())
                .insert(self.space);
        }
        self.property(
            &id,
            self.cnc,
            "EngineeringUnits",
            DataTypeId::EUInformation,
            eu(unit),
        );
        id
    }
}

fn path_of(id: &NodeId) -> String {
    match &id.identifier {
        opcua::types::Identifier::String(s) => s.as_ref().to_string(),
        other => other.to_string(),
    }
}

const AXIS_LETTERS: [&str; 9] = ["X", "Y", "Z", "A", "B", "C", "U", "V", "W"];

fn build_model(app: &App, space: &mut AddressSpace, ns: u16, cnc: u16) -> Model {
    let config = &app.config;
    let t = |i: u32| NodeId::new(cnc, i);
    let interface = NodeId::new(ns, "CncInterface");
    ObjectBuilder::new(
        &interface,
        QualifiedName::new(cnc, "CncInterface"),
        "CncInterface",
    )
    .has_type_definition(t(1007))
    .organized_by(ObjectId::ObjectsFolder)
    .event_notifier(EventNotifier::SUBSCRIBE_TO_EVENTS)
    .insert(space);
    let mut add = NodeAdder { space, ns, cnc };
    let version = env!("CARGO_PKG_VERSION");
    for (name, value) in [
        ("VendorName", "rtcnc".to_string()),
        ("VendorRevision", version.to_string()),
        ("Version", "1.0.0".to_string()),
        ("CncTypeName", format!("rtcnc {}", config.machine.name)),
    ] {
        add.property(
            &interface,
            cnc,
            name,
            DataTypeId::String,
            Variant::from(value),
        );
    }
    let lists = [
        ("CncAxisList", 1008u32),
        ("CncSpindleList", 1009),
        ("CncChannelList", 1010),
    ];
    for (name, type_id) in lists {
        let id = NodeId::new(ns, format!("CncInterface.{name}"));
        add.object(&id, name, t(type_id), &interface);
    }
    let channel = NodeId::new(ns, "CncInterface.CncChannelList.Channel1");
    add.object(
        &channel,
        "Channel1",
        t(1002),
        &NodeId::new(ns, "CncInterface.CncChannelList"),
    );
    let sim = matches!(
        config.fieldbus.kind,
        rtcnc_kernel::config::FieldbusKind::Sim
    );
    let joint_names: Vec<String> = config.joints.iter().map(|j| j.name.clone()).collect();
    let mut axes = Vec::new();
    for (i, letter) in AXIS_LETTERS.iter().enumerate() {
        let Some(axis) = config.axes.get(&letter.to_ascii_lowercase()) else {
            continue;
        };
        let id = NodeId::new(ns, format!("CncInterface.CncAxisList.{letter}"));
        add.object(
            &id,
            letter,
            t(1004),
            &NodeId::new(ns, "CncInterface.CncAxisList"),
        );
        let rotational = (3..=5).contains(&i);
        let unit = if rotational {
            cnc::DEGREE
        } else {
            cnc::MILLIMETRE
        };
        add.variable(&id, "ActStatus", t(3004), None);
        add.variable(&id, "IsReferenced", DataTypeId::Boolean, None);
        add.variable(&id, "IsRotational", DataTypeId::Boolean, None);
        add.position(&id, "PosDirect", unit);
        add.position(&id, "PosIndirect", unit);
        add.variable(&id, "ZeroOffset", DataTypeId::Double, Some(unit));
        drive_variables(&mut add, &id);
        let joints = axis
            .joints
            .iter()
            .filter_map(|j| joint_names.iter().position(|n| n == j))
            .collect();
        axes.push((letter.to_string(), id, joints, rotational));
    }
    let spindle = config.spindle.as_ref().map(|_| {
        let id = NodeId::new(ns, "CncInterface.CncSpindleList.S");
        add.object(
            &id,
            "S",
            t(1005),
            &NodeId::new(ns, "CncInterface.CncSpindleList"),
        );
        add.variable(
            &id,
            "ActSpeed",
            DataTypeId::Double,
            Some(cnc::REVOLUTIONS_PER_MINUTE),
        );
        add.variable(
            &id,
            "CmdSpeed",
            DataTypeId::Double,
            Some(cnc::REVOLUTIONS_PER_MINUTE),
        );
        add.variable(&id, "ActOverride", DataTypeId::Double, Some(cnc::PERCENT));
        add.variable(&id, "CmdOverride", DataTypeId::Double, Some(cnc::PERCENT));
        add.variable(&id, "ActStatus", t(3005), None);
        add.variable(&id, "ActTurnDirection", t(3001), None);
        add.variable(&id, "ActGear", DataTypeId::UInt32, None);
        add.variable(&id, "CmdGear", DataTypeId::UInt32, None);
        add.position(&id, "AnglePos", cnc::DEGREE);
        drive_variables(&mut add, &id);
        id
    });
    let c = &channel;
    add.property(c, cnc, "Id", DataTypeId::UInt32, Variant::from(1u32));
    for (name, dt) in [
        ("ActStatus", t(3003)),
        ("ActProgramStatus", t(3002)),
        ("ActOperationMode", t(3006)),
        ("CmdOperationMode", t(3006)),
    ] {
        add.variable(c, name, dt, None);
    }
    for name in [
        "ActProgramName",
        "ActProgramFile",
        "ActMainProgramName",
        "ActMainProgramFile",
        "ActProgramLine",
        "ActMainProgramLine",
    ] {
        add.variable(c, name, DataTypeId::String, None);
    }
    add.array_variable(c, "ActProgramBlock", DataTypeId::String);
    add.array_variable(c, "ActGFunctions", DataTypeId::UInt32);
    add.array_variable(c, "ActMFunctions", DataTypeId::UInt32);
    add.variable(c, "ActModalOffsetFunction", DataTypeId::UInt32, None);
    add.variable(c, "ToolId", DataTypeId::UInt32, None);
    add.variable(c, "BlockMode", DataTypeId::Boolean, None);
    add.variable(c, "FeedHold", DataTypeId::Boolean, None);
    let feed = Some(cnc::MILLIMETRE_PER_MINUTE);
    add.variable(c, "ActFeedrate", DataTypeId::Double, feed);
    add.variable(c, "CmdFeedrate", DataTypeId::Double, feed);
    add.variable(c, "DryRunFeed", DataTypeId::Double, feed);
    add.variable(
        c,
        "ActJogIncrement",
        DataTypeId::Double,
        Some(cnc::MILLIMETRE),
    );
    add.variable(c, "ActOverride", DataTypeId::Double, Some(cnc::PERCENT));
    add.variable(c, "CmdOverride", DataTypeId::Double, Some(cnc::PERCENT));
    for system in ["Bcs", "Wcs"] {
        for letter in ["X", "Y", "Z", "A", "B", "C"] {
            let unit = if "ABC".contains(letter) {
                cnc::DEGREE
            } else {
                cnc::MILLIMETRE
            };
            add.position(c, &format!("PosTcp{system}{letter}"), unit);
        }
    }
    // The channel organises its axes and spindle, as the specification's example does.
    for (_, id, _, _) in &axes {
        add.space
            .insert_reference(c, id, opcua::types::ReferenceTypeId::Organizes);
    }
    if let Some(s) = &spindle {
        add.space
            .insert_reference(c, s, opcua::types::ReferenceTypeId::Organizes);
    }
    for (_, id, _, _) in &axes {
        add.variable(id, "ActChannel", DataTypeId::NodeId, None);
    }
    if let Some(s) = &spindle {
        add.variable(s, "ActChannel", DataTypeId::NodeId, None);
    }
    Model {
        ns,
        cnc,
        interface,
        channel,
        axes,
        spindle,
        simulated: sim,
    }
}

/// Namespace indices of the companion specifications the identification uses.
struct Namespaces {
    di: u16,
    machinery: u16,
    machine_tool: u16,
}

/// The machine in the Machines folder of OPC 40001-1 (Machinery), with its umati
/// identification (OPC 40501-1's `MachineToolIdentificationType`, a
/// `MachineIdentificationType`: manufacturer, model, serial number, software revision,
/// year of construction, product instance URI) and the CncInterface organised below it.
/// Made when the machine file names the manufacturer and the serial number, which the
/// identification must have.
fn identification(
    app: &App,
    section: &OpcUaSection,
    space: &mut AddressSpace,
    model: &Model,
    namespaces: Namespaces,
) {
    let Namespaces {
        di,
        machinery,
        machine_tool,
    } = namespaces;
    let (Some(manufacturer), Some(serial)) = (&section.manufacturer, &section.serial_number) else {
        return;
    };
    let ns = model.ns;
    let machine = NodeId::new(ns, "Machine");
    let name = app.config.machine.name.clone();
    ObjectBuilder::new(
        &machine,
        QualifiedName::new(ns, name.as_str()),
        name.as_str(),
    )
    .has_type_definition(ObjectTypeId::BaseObjectType)
    .organized_by(NodeId::new(machinery, 1001u32))
    .insert(space);
    space.insert_reference(
        &machine,
        &model.interface,
        opcua::types::ReferenceTypeId::Organizes,
    );
    let id = NodeId::new(ns, "Machine.Identification");
    ObjectBuilder::new(
        &id,
        QualifiedName::new(di, "Identification"),
        "Identification",
    )
    .has_type_definition(NodeId::new(
        machine_tool,
        crate::nodeset::MACHINE_TOOL_IDENTIFICATION_TYPE,
    ))
    .component_of(machine.clone())
    .insert(space);
    let mut add = NodeAdder {
        space,
        ns,
        cnc: model.cnc,
    };
    let model_name = section.model.clone().unwrap_or_else(|| name.clone());
    let uri = format!(
        "urn:{}:{}:{}",
        slug(manufacturer),
        slug(&model_name),
        slug(serial)
    );
    add.property(
        &id,
        di,
        "Manufacturer",
        DataTypeId::LocalizedText,
        Variant::from(LocalizedText::new("", manufacturer)),
    );
    add.property(
        &id,
        di,
        "Model",
        DataTypeId::LocalizedText,
        Variant::from(LocalizedText::new("", &model_name)),
    );
    add.property(
        &id,
        di,
        "SerialNumber",
        DataTypeId::String,
        Variant::from(serial.clone()),
    );
    add.property(
        &id,
        di,
        "SoftwareRevision",
        DataTypeId::String,
        Variant::from(format!("rtcnc {}", env!("CARGO_PKG_VERSION"))),
    );
    add.property(
        &id,
        di,
        "ProductInstanceUri",
        DataTypeId::String,
        Variant::from(uri),
    );
    if let Some(year) = section.year_of_construction {
        add.property(
            &id,
            machinery,
            "YearOfConstruction",
            DataTypeId::UInt16,
            Variant::from(year),
        );
    }
}

/// The mandatory variables of `CncDriveType` (`ActChannel` is added with the channel).
fn drive_variables(add: &mut NodeAdder<'_>, id: &NodeId) {
    add.variable(id, "ActLoad", DataTypeId::Double, Some(cnc::PERCENT));
    add.variable(id, "ActPower", DataTypeId::Double, None);
    add.variable(id, "ActTorque", DataTypeId::Double, None);
    add.variable(id, "CmdTorque", DataTypeId::Double, None);
    add.variable(id, "IsInactive", DataTypeId::Boolean, None);
    add.variable(id, "IsVirtual", DataTypeId::Boolean, None);
}

fn good(v: impl Into<Variant>) -> Value {
    Value::Good(v.into())
}

/// Every served value of the model from one status document.
fn values(model: &Model, app: &App, s: &Status, program_block: &[String]) -> Vec<(NodeId, Value)> {
    let mut out: Vec<(NodeId, Value)> = Vec::with_capacity(256);
    let c = path_of(&model.channel);
    let mut put = |path: String, v: Value| out.push((model.id(&path), v));
    let modal = s.modal.as_ref();
    put(
        format!("{c}.ActStatus"),
        good(cnc::channel_status(s) as i32),
    );
    put(
        format!("{c}.ActProgramStatus"),
        good(cnc::program_status(s) as i32),
    );
    let mode = cnc::operation_mode(s) as i32;
    put(format!("{c}.ActOperationMode"), good(mode));
    put(format!("{c}.CmdOperationMode"), good(mode));
    let name = s.program.clone().unwrap_or_default();
    let file = s
        .program
        .as_ref()
        .and_then(|n| app.program_path(n).ok())
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    put(format!("{c}.ActProgramName"), good(name.clone()));
    put(format!("{c}.ActMainProgramName"), good(name));
    put(format!("{c}.ActProgramFile"), good(file.clone()));
    put(format!("{c}.ActMainProgramFile"), good(file));
    put(format!("{c}.ActProgramLine"), good(s.line.to_string()));
    put(format!("{c}.ActMainProgramLine"), good(s.line.to_string()));
    put(format!("{c}.ActProgramBlock"), good(program_block.to_vec()));
    let (g, m, offset, feed) = match modal {
        Some(m) => (
            cnc::code_numbers(&m.g_codes, 'G'),
            cnc::code_numbers(&m.m_codes, 'M'),
            cnc::work_system_number(&m.work_system),
            Value::Good(Variant::from(if m.units == "inch" {
                m.feed_rate * 25.4
            } else {
                m.feed_rate
            })),
        ),
        None => (Vec::new(), Vec::new(), 0, Value::Absent),
    };
    put(format!("{c}.ActGFunctions"), good(g));
    put(format!("{c}.ActMFunctions"), good(m));
    put(format!("{c}.ActModalOffsetFunction"), good(offset));
    put(format!("{c}.CmdFeedrate"), feed);
    put(format!("{c}.ActFeedrate"), good(s.path_speed * 60.0));
    put(format!("{c}.ToolId"), good(s.tool));
    put(format!("{c}.BlockMode"), good(s.single_block));
    put(format!("{c}.FeedHold"), good(s.state == "held"));
    put(format!("{c}.DryRunFeed"), Value::Absent);
    put(format!("{c}.ActJogIncrement"), Value::Absent);
    put(format!("{c}.ActOverride"), good(s.overrides.feed * 100.0));
    put(format!("{c}.CmdOverride"), good(s.overrides.feed * 100.0));
    // Per axis: commanded is the set-point, actual the mean feedback of its joints.
    let actual = |joints: &[usize]| -> Option<f64> {
        let fb: Vec<f64> = joints
            .iter()
            .filter_map(|&j| s.joints.get(j).map(|x| x.feedback))
            .collect();
        (!fb.is_empty()).then(|| fb.iter().sum::<f64>() / fb.len() as f64)
    };
    for letter in ["X", "Y", "Z", "A", "B", "C"] {
        let axis = model.axes.iter().find(|a| a.0 == letter);
        let cmd = s.machine_position.0.get(letter).copied();
        let work = s.work_position.0.get(letter).copied();
        let rem = s.distance_to_go.0.get(letter).copied().unwrap_or(0.0);
        let act = axis.and_then(|a| actual(&a.2));
        for (system, cmd_pos, act_pos) in [
            ("Bcs", cmd, act),
            (
                "Wcs",
                work,
                // The work position of the feedback: the same offsets taken off.
                work.zip(cmd).zip(act).map(|((w, c), a)| w + (a - c)),
            ),
        ] {
            let p = format!("{c}.PosTcp{system}{letter}");
            match (cmd_pos, act_pos) {
                (Some(cp), Some(ap)) => {
                    put(format!("{p}.CmdPos"), good(cp));
                    put(format!("{p}.ActPos"), good(ap));
                    put(format!("{p}.RemDist"), good(rem));
                }
                _ => {
                    for m in ["CmdPos", "ActPos", "RemDist"] {
                        put(format!("{p}.{m}"), Value::Absent);
                    }
                }
            }
            put(p, Value::Absent);
        }
    }
    for (letter, id, joints, rotational) in &model.axes {
        let a = path_of(id);
        let speed = joints
            .iter()
            .filter_map(|&j| s.joints.get(j).map(|x| x.velocity.abs()))
            .fold(0.0, f64::max);
        put(
            format!("{a}.ActStatus"),
            good(cnc::axis_status(s.ready, speed) as i32),
        );
        let homed = !joints.is_empty()
            && joints
                .iter()
                .all(|&j| s.joints.get(j).is_some_and(|x| x.homed));
        put(format!("{a}.IsReferenced"), good(homed));
        put(format!("{a}.IsRotational"), good(*rotational));
        let cmd = s.machine_position.0.get(letter).copied().unwrap_or(0.0);
        let act = actual(joints).unwrap_or(cmd);
        put(format!("{a}.PosIndirect.CmdPos"), good(cmd));
        put(format!("{a}.PosIndirect.ActPos"), good(act));
        put(
            format!("{a}.PosIndirect.RemDist"),
            good(s.distance_to_go.0.get(letter).copied().unwrap_or(0.0)),
        );
        for m in ["", ".CmdPos", ".ActPos", ".RemDist"] {
            put(format!("{a}.PosDirect{m}"), Value::Absent);
        }
        put(format!("{a}.PosIndirect"), Value::Absent);
        let zero = s
            .work_position
            .0
            .get(letter)
            .map(|w| cmd - w)
            .map_or(Value::Absent, good);
        put(format!("{a}.ZeroOffset"), zero);
        put(format!("{a}.ActChannel"), good(model.channel.clone()));
        drive_values(&mut put, &a, model.simulated);
    }
    if let Some(id) = &model.spindle {
        let p = path_of(id);
        put(format!("{p}.ActSpeed"), good(s.spindle.rpm));
        put(format!("{p}.CmdSpeed"), good(s.spindle.command_rpm));
        put(
            format!("{p}.ActOverride"),
            good(s.overrides.spindle * 100.0),
        );
        put(
            format!("{p}.CmdOverride"),
            good(s.overrides.spindle * 100.0),
        );
        put(
            format!("{p}.ActStatus"),
            good(cnc::spindle_status(s) as i32),
        );
        put(
            format!("{p}.ActTurnDirection"),
            good(cnc::turn_direction(s) as i32),
        );
        put(format!("{p}.ActGear"), Value::Absent);
        put(format!("{p}.CmdGear"), Value::Absent);
        for m in ["", ".CmdPos", ".ActPos", ".RemDist"] {
            put(format!("{p}.AnglePos{m}"), Value::Absent);
        }
        put(format!("{p}.ActChannel"), good(model.channel.clone()));
        drive_values(&mut put, &p, model.simulated);
    }
    out
}

fn drive_values(put: &mut impl FnMut(String, Value), path: &str, simulated: bool) {
    for name in ["ActLoad", "ActPower", "ActTorque", "CmdTorque"] {
        put(format!("{path}.{name}"), Value::Absent);
    }
    put(format!("{path}.IsInactive"), good(false));
    put(format!("{path}.IsVirtual"), good(simulated));
}

/// The server's certificate folder.
fn pki_dir(app: &App, section: &OpcUaSection) -> PathBuf {
    match &section.pki {
        Some(p) => app.config.resolve(p),
        None => app
            .options
            .config_path
            .parent()
            .unwrap_or(std::path::Path::new("."))
            .join("opcua-pki"),
    }
}

/// Starts the server and the tasks that feed it; returns once it listens.
pub async fn start(app: Arc<App>, section: OpcUaSection) -> anyhow::Result<()> {
    let name = slug(&app.config.machine.name);
    let pki = pki_dir(&app, &section);
    let host = section
        .host_name
        .clone()
        .unwrap_or_else(|| section.listen.ip().to_string());
    let (sampling_tx, sampling_rx) = tokio::sync::watch::channel(Sampling::default());
    let mut builder = ServerBuilder::new()
        .application_name(format!("rtcnc {}", app.config.machine.name))
        .application_uri(format!("urn:rtcnc:{name}"))
        .product_uri("urn:rtcnc")
        .create_sample_keypair(true)
        .pki_dir(pki.clone())
        .certificate_path("own/cert.der")
        .private_key_path("private/private.pem")
        .trust_client_certs(section.trust_all_clients)
        .host(host)
        .port(section.listen.port())
        .max_sessions(section.max_sessions)
        .subscription_poll_interval_ms(section.min_interval_ms.ceil() as u64)
        .with_authenticator(Arc::new(UsersAuth {
            app: Arc::clone(&app),
            anonymous: section.anonymous,
        }))
        .with_node_manager(simple_node_manager_imports(
            {
                let mut imports = crate::nodeset::identification_imports()?;
                imports.push(Box::new(CncTypes::load()?));
                imports
            },
            "companion types",
        ))
        .with_node_manager(machine_node_manager(
            format!("urn:rtcnc:{name}:machine"),
            MACHINE_MANAGER,
            sampling_tx,
        ))
        .discovery_urls(vec!["/".to_string()]);
    {
        let limits = builder.limits_mut();
        limits.subscriptions.min_publishing_interval_ms = section.min_interval_ms;
        // Sampling goes down to the servo period, where the machine's status snapshot is
        // published; publishing stays at `min_interval_ms`.
        limits.subscriptions.min_sampling_interval_ms =
            app.config.servo_period().as_secs_f64() * 1e3;
        // A monitored item keeps the samples of up to 2 s at 1 ms between two
        // publications (async-opcua's default keeps 10).
        limits.subscriptions.max_monitored_item_queue_size = MAX_QUEUE_SIZE;
    }
    let endpoints = [
        (
            "basic256sha256_sign",
            SecurityPolicy::Basic256Sha256,
            MessageSecurityMode::Sign,
        ),
        (
            "basic256sha256_sign_encrypt",
            SecurityPolicy::Basic256Sha256,
            MessageSecurityMode::SignAndEncrypt,
        ),
        (
            "aes256sha256rsapss_sign",
            SecurityPolicy::Aes256Sha256RsaPss,
            MessageSecurityMode::Sign,
        ),
        (
            "aes256sha256rsapss_sign_encrypt",
            SecurityPolicy::Aes256Sha256RsaPss,
            MessageSecurityMode::SignAndEncrypt,
        ),
    ];
    for (id, policy, mode) in endpoints {
        builder = builder.add_endpoint(id, ServerEndpoint::new("/", policy, mode, &[]));
    }
    if section.allow_unsecured {
        builder = builder.add_endpoint("none", ServerEndpoint::new_none("/", &[]));
    }
    // The folder holds the server's private key: its owner's only, before the key is made
    // in it, and the key file too.
    {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::create_dir_all(&pki).map_err(|e| anyhow::anyhow!("{}: {e}", pki.display()))?;
        std::fs::set_permissions(&pki, std::fs::Permissions::from_mode(0o700))
            .map_err(|e| anyhow::anyhow!("{}: {e}", pki.display()))?;
    }
    let (server, handle) = builder
        .build()
        .map_err(|e| anyhow::anyhow!("OPC UA server: {e}"))?;
    {
        use std::os::unix::fs::PermissionsExt as _;
        let key = pki.join("private").join("private.pem");
        if key.exists() {
            std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600))
                .map_err(|e| anyhow::anyhow!("{}: {e}", key.display()))?;
        }
    }
    let listener = tokio::net::TcpListener::bind(section.listen)
        .await
        .map_err(|e| anyhow::anyhow!("OPC UA: listening on {}: {e}", section.listen))?;
    let local = listener.local_addr()?;
    let manager = handle
        .node_managers()
        .get_by_name::<MachineNodeManager>(MACHINE_MANAGER)
        .ok_or_else(|| anyhow::anyhow!("OPC UA: the machine's node manager is missing"))?;
    let ns = handle
        .get_namespace_index(&format!("urn:rtcnc:{name}:machine"))
        .ok_or_else(|| anyhow::anyhow!("OPC UA: the machine's namespace is missing"))?;
    let cnc = handle
        .get_namespace_index(CNC_NAMESPACE)
        .ok_or_else(|| anyhow::anyhow!("OPC UA: the CNC namespace is missing"))?;
    let model = {
        let mut space = manager.address_space().write();
        let model = build_model(&app, &mut space, ns, cnc);
        let di = handle.get_namespace_index(crate::nodeset::DI_NAMESPACE);
        let machinery = handle.get_namespace_index(crate::nodeset::MACHINERY_NAMESPACE);
        let machine_tool = handle.get_namespace_index(crate::nodeset::MACHINE_TOOL_NAMESPACE);
        if let (Some(di), Some(machinery), Some(machine_tool)) = (di, machinery, machine_tool) {
            identification(
                &app,
                &section,
                &mut space,
                &model,
                Namespaces {
                    di,
                    machinery,
                    machine_tool,
                },
            );
        }
        model
    };
    tokio::spawn(async move {
        if let Err(e) = server.run_with(listener).await {
            eprintln!("rtcnc api: OPC UA server stopped: {e}");
        }
    });
    println!(
        "rtcnc api: OPC UA on opc.tcp://{local}/ (certificate in {})",
        pki.display()
    );
    let model = Arc::new(model);
    tokio::spawn(feed_values(
        Arc::clone(&app),
        Arc::clone(&manager),
        handle.clone(),
        Arc::clone(&model),
        sampling_rx,
    ));
    tokio::spawn(feed_events(app, handle, model));
    Ok(())
}

/// Largest queue of a monitored item: 2 s of samples at 1 kHz, so a 1 ms item keeps every
/// one of a batch of the trace that a loaded machine delivers late (and of a client that
/// sends its publish requests late).
const MAX_QUEUE_SIZE: usize = 2000;

/// The API's status documents come this often (crates/api/src/machine.rs).
const API_STATUS_PERIOD_MS: f64 = 10.0;

/// The nodes whose values the machine's trace carries, each servo period's: the axes'
/// set-points and feedback (`PosIndirect`, and the channel's `PosTcpBcs` of X to C) and the
/// path speed (`ActFeedrate`). The rest (distances to go, work coordinates, states) only
/// the status snapshot has.
fn trace_nodes(model: &Model) -> TraceNodes {
    let c = path_of(&model.channel);
    let mut out = vec![(model.id(&format!("{c}.ActFeedrate")), Source::Feedrate)];
    for (letter, id, joints, _) in &model.axes {
        let Some(axis) = AXIS_LETTERS.iter().position(|l| l == letter) else {
            continue;
        };
        let a = path_of(id);
        let actual = Source::Actual(axis, joints.clone());
        out.push((
            model.id(&format!("{a}.PosIndirect.CmdPos")),
            Source::Command(axis),
        ));
        out.push((model.id(&format!("{a}.PosIndirect.ActPos")), actual.clone()));
        // Without joints the status document has no actual position there (Bad_NotSupported).
        if axis < 6 && !joints.is_empty() {
            let p = format!("{c}.PosTcpBcs{letter}");
            out.push((model.id(&format!("{p}.CmdPos")), Source::Command(axis)));
            out.push((model.id(&format!("{p}.ActPos")), actual));
        }
    }
    Arc::new(out)
}

/// Where the values come from, for the monitored items that sample.
#[derive(Debug, Clone, PartialEq)]
struct Plan {
    /// The trace feeds the nodes it carries: an item on one of them samples faster than
    /// the status documents come.
    trace: bool,
    /// The step (servo periods) of every item on those nodes, while the trace feeds them.
    steps: HashMap<opcua::server::MonitoredItemHandle, u64>,
    /// The fastest interval (ms) asked of the other nodes (of all, without the trace).
    snapshot: f64,
}

fn plan(items: &Sampling, trace: &HashSet<NodeId>, period_ms: f64) -> Plan {
    let on = items
        .values()
        .any(|(n, i)| trace.contains(n) && *i > 0.0 && *i < API_STATUS_PERIOD_MS);
    let steps = items
        .iter()
        .filter(|(_, (n, _))| on && trace.contains(n))
        .map(|(h, (_, i))| (*h, crate::sampling::step_of(*i, period_ms)))
        .collect();
    let snapshot = crate::sampling::fastest_interval(
        items
            .values()
            .filter(|(n, _)| !on || !trace.contains(n))
            .map(|(_, i)| *i),
    );
    Plan {
        trace: on,
        steps,
        snapshot,
    }
}

/// The next batch of the trace's samples, while it feeds.
async fn next_batch(
    feed: &mut Option<TraceFeed>,
) -> Arc<Vec<rtcnc_kernel::link::layout::TraceSample>> {
    if let Some(f) = feed.as_mut() {
        if let Some(b) = f.recv().await {
            return b;
        }
    }
    std::future::pending().await
}

/// Sets the model's values, only those that changed, so subscriptions see changes: from
/// the API's status documents (100 a second) while no monitored item samples faster. When
/// one does on a value the machine's trace carries (positions, path speed), those values
/// come from the trace, every servo period's sample in batches, each item taking one per
/// its own sampling interval (`TraceFeed`); when one does on another value, the others come
/// from the machine's shared-memory status snapshot read directly, as often as the fastest
/// such item asks, down to the machine's status period (its servo period). Reading the
/// trace and the snapshot never makes the machine wait.
async fn feed_values(
    app: Arc<App>,
    manager: Arc<MachineNodeManager>,
    handle: ServerHandle,
    model: Arc<Model>,
    mut sampling: tokio::sync::watch::Receiver<Sampling>,
) {
    let mut rx = app.machine.status_watch();
    let nodes = trace_nodes(&model);
    let trace_ids: Arc<HashSet<NodeId>> =
        Arc::new(nodes.iter().map(|(id, _)| id.clone()).collect());
    let period_ms = app.config.servo_period().as_secs_f64() * 1e3;
    let period_ticks = (app.config.servo_period().as_nanos() / 100) as i64;
    let mut publisher = Publisher {
        app: Arc::clone(&app),
        manager: Arc::clone(&manager),
        handle: handle.clone(),
        model,
        last: HashMap::new(),
        program: None,
        connected: true,
        clock: Clock::new(period_ticks),
        last_cycle: None,
        trace_ids: Arc::clone(&trace_ids),
        skip_trace: false,
    };
    publisher.publish(&rx.borrow_and_update().clone());
    let mut feed: Option<TraceFeed> = None;
    loop {
        let plan = plan(&sampling.borrow_and_update(), &trace_ids, period_ms);
        if plan.trace {
            feed.get_or_insert_with(|| {
                TraceFeed::new(
                    app.machine.subscribe_trace(),
                    Arc::clone(&nodes),
                    period_ticks,
                    publisher.clock.zero(),
                    publisher.last_cycle,
                )
            })
            .set_steps(&plan.steps);
        } else {
            feed = None;
        }
        publisher.set_skip_trace(plan.trace);
        if plan.snapshot < API_STATUS_PERIOD_MS {
            let status_period_ms = app
                .machine
                .client()
                .map(|c| c.header().status_period_ns as f64 * 1e-6)
                .unwrap_or(1.0);
            let period =
                Duration::from_secs_f64(plan.snapshot.max(status_period_ms).max(0.1) * 1e-3);
            // A thread of its own: the runtime's timer ticks in whole milliseconds.
            let stop = Arc::new(AtomicBool::new(false));
            let sampler = {
                let (app, stop) = (Arc::clone(&app), Arc::clone(&stop));
                tokio::task::spawn_blocking(move || {
                    sample_directly(&app, &mut publisher, &mut rx, period, &stop);
                    (publisher, rx)
                })
            };
            let changed = loop {
                tokio::select! {
                    r = sampling.changed() => break r,
                    b = next_batch(&mut feed) => {
                        if let Some(f) = feed.as_mut() {
                            f.feed(&b, &manager, handle.subscriptions(), app.machine.status().link.trace_dropped);
                        }
                    }
                }
            };
            stop.store(true, Ordering::Relaxed);
            let Ok((p, r)) = sampler.await else {
                return;
            };
            (publisher, rx) = (p, r);
            if changed.is_err() {
                return;
            }
            // The API's document at hand is older than the snapshot just set: the next
            // one is not.
            rx.borrow_and_update();
        } else {
            tokio::select! {
                r = rx.changed() => {
                    if r.is_err() {
                        return;
                    }
                    publisher.publish(&rx.borrow_and_update().clone());
                }
                r = sampling.changed() => {
                    if r.is_err() {
                        return;
                    }
                }
                b = next_batch(&mut feed) => {
                    if let Some(f) = feed.as_mut() {
                        f.feed(&b, &manager, handle.subscriptions(), app.machine.status().link.trace_dropped);
                    }
                }
            }
        }
    }
}

/// Sets the values from the machine's snapshot every `period` until `stop`; from the API's
/// documents while the machine is not attached.
fn sample_directly(
    app: &App,
    publisher: &mut Publisher,
    rx: &mut tokio::sync::watch::Receiver<Arc<Status>>,
    period: Duration,
    stop: &AtomicBool,
) {
    let mut cycle = None;
    let mut next = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        match direct_status(app, &mut cycle) {
            Some(Some(status)) => publisher.publish(&status),
            Some(None) => {}
            // The machine is gone: the API's document says so.
            None if rx.has_changed().unwrap_or(false) => {
                publisher.publish(&rx.borrow_and_update().clone());
            }
            None => {}
        }
        next += period;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else {
            // Late (a loaded machine): the next read is a period from now, not a burst.
            next = now;
        }
    }
}

/// The machine's status snapshot as a status document, when it is newer than `cycle`
/// (`Some(None)`: no newer one; `None`: the machine is not attached). The program's name
/// and the deadline misses, which change slowly, are the API's.
fn direct_status(app: &App, cycle: &mut Option<u64>) -> Option<Option<Status>> {
    let client = app.machine.client().ok()?;
    let wire = client.status();
    if *cycle == Some(wire.cycle) {
        return Some(None);
    }
    *cycle = Some(wire.cycle);
    let api = app.machine.status();
    Some(Some(rtcnc_api::machine::status_document(
        &wire,
        &app.machine.meta(),
        api.deadline_misses,
        &client.watch(),
        &[],
        api.program.clone(),
    )))
}

/// Sets the values of one status document.
struct Publisher {
    app: Arc<App>,
    manager: Arc<MachineNodeManager>,
    handle: ServerHandle,
    model: Arc<Model>,
    last: HashMap<NodeId, Value>,
    /// The loaded program's name and lines.
    program: Option<(String, Vec<String>)>,
    connected: bool,
    /// The source timestamps: the machine's time of a status on the wall clock.
    clock: Clock,
    /// The machine's cycle of the last status set.
    last_cycle: Option<u64>,
    /// The nodes whose values the machine's trace carries.
    trace_ids: Arc<HashSet<NodeId>>,
    /// The trace sets those (while the machine is attached).
    skip_trace: bool,
}

impl Publisher {
    /// Leaves the trace's nodes to the trace, or takes them back (and sets them with the
    /// next status, changed or not).
    fn set_skip_trace(&mut self, on: bool) {
        if on != self.skip_trace {
            self.skip_trace = on;
            let ids = &self.trace_ids;
            self.last.retain(|id, _| !ids.contains(id));
        }
    }

    fn publish(&mut self, status: &Status) {
        // While the machine process is gone the values are its last ones: every value is set
        // again with a status that says so, and again when it is back.
        if status.connected != self.connected {
            self.connected = status.connected;
            self.last.clear();
            self.clock.reset();
            self.last_cycle = None;
        }
        let good_status = if self.connected {
            StatusCode::Good
        } else {
            StatusCode::UncertainLastUsableValue
        };
        // The program's text, read again when another program is loaded.
        let name = status.program.clone().unwrap_or_default();
        if self.program.as_ref().is_none_or(|(n, _)| *n != name) {
            let lines = self
                .app
                .read_program(&name)
                .map(|t| t.lines().map(str::to_string).collect())
                .unwrap_or_default();
            self.program = Some((name, lines));
        }
        let block: Vec<String> = self
            .program
            .as_ref()
            .and_then(|(_, lines)| lines.get((status.line as usize).checked_sub(1)?))
            .map(|l| vec![l.clone()])
            .unwrap_or_default();
        let now = DateTime::now();
        let source = if self.connected {
            self.last_cycle = Some(status.cycle);
            DateTime::from(
                self.clock
                    .stamp((status.time_s * 1e7).round() as i64, now.ticks()),
            )
        } else {
            now
        };
        let skip_trace = self.skip_trace && self.connected;
        let mut changed: Vec<(NodeId, DataValue)> = Vec::new();
        for (id, v) in values(&self.model, &self.app, status, &block) {
            if self.last.get(&id) == Some(&v) || (skip_trace && self.trace_ids.contains(&id)) {
                continue;
            }
            let dv = match &v {
                Value::Good(x) => DataValue {
                    value: Some(x.clone()),
                    status: Some(good_status),
                    source_timestamp: Some(source),
                    server_timestamp: Some(now),
                    ..Default::default()
                },
                // An empty value: the status is only served beside a value.
                Value::Absent => DataValue {
                    value: Some(Variant::Empty),
                    status: Some(StatusCode::BadNotSupported),
                    source_timestamp: Some(source),
                    server_timestamp: Some(now),
                    ..Default::default()
                },
            };
            self.last.insert(id.clone(), v);
            changed.push((id, dv));
        }
        if !changed.is_empty() {
            let _ = self.manager.set_values(
                self.handle.subscriptions(),
                changed.iter().map(|(id, dv)| (id, None, dv.clone())),
            );
        }
    }
}

/// Faults and operator messages as events of the CncInterface (and the Server object,
/// where generic clients listen).
async fn feed_events(app: Arc<App>, handle: ServerHandle, model: Arc<Model>) {
    let mut rx = app.machine.subscribe_events();
    loop {
        let e = match rx.recv().await {
            Ok(e) => e,
            Err(RecvError::Lagged(_)) => continue,
            Err(RecvError::Closed) => return,
        };
        notify(&handle, &model, &e);
    }
}

fn event_id(e: &Event) -> ByteString {
    let mut id = b"rtcnc".to_vec();
    id.extend_from_slice(&e.seq.to_be_bytes());
    id.extend_from_slice(&opcua::types::DateTime::now().ticks().to_be_bytes());
    ByteString::from(id)
}

fn notify(handle: &ServerHandle, model: &Model, e: &Event) {
    let server: NodeId = ObjectId::Server.into();
    let namespaces = handle.type_tree().read().namespaces().clone();
    let time = DateTime::now();
    match e.kind.as_str() {
        "fault" => {
            let code = e.code.clone().unwrap_or_default();
            let mut ev = CncAlarmEvent::new_event(
                CncAlarmEvent::event_type_id_from_index(model.cnc),
                event_id(e),
                LocalizedText::new("en", &e.message),
                &namespaces,
                time,
            );
            let mut aux = Vec::new();
            if let Some(l) = e.line {
                aux.push(format!("line={l}"));
            }
            if let Some(j) = &e.joint {
                aux.push(format!("joint={j}"));
            }
            ev.alarm_identifier = code.clone().into();
            ev.aux_parameters = aux.join(" ").into();
            ev.help_source = "docs/safety.md".into();
            let alarm = &mut ev.base.base;
            alarm.active_state.id = true;
            alarm.active_state.base.value = LocalizedText::new("en", "Active");
            let condition = &mut alarm.base.base;
            condition.condition_name = code.into();
            condition.retain = false;
            condition.enabled_state.id = true;
            condition.enabled_state.base.value = LocalizedText::new("en", "Enabled");
            let base = &mut condition.base;
            base.source_node = model.channel.clone();
            base.source_name = "Channel1".into();
            base.severity = 800;
            handle.subscriptions().notify_events(
                [
                    (&ev as &dyn opcua::nodes::Event, &model.interface),
                    (&ev as &dyn opcua::nodes::Event, &server),
                ]
                .into_iter(),
            );
        }
        "message" => {
            let mut ev = CncMessageEvent::new_event(
                CncMessageEvent::event_type_id_from_index(model.cnc),
                event_id(e),
                LocalizedText::new("en", &e.message),
                &namespaces,
                time,
            );
            ev.base.source_node = model.channel.clone();
            ev.base.source_name = "Channel1".into();
            ev.base.severity = 100;
            handle.subscriptions().notify_events(
                [
                    (&ev as &dyn opcua::nodes::Event, &model.interface),
                    (&ev as &dyn opcua::nodes::Event, &server),
                ]
                .into_iter(),
            );
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use opcua::server::MonitoredItemHandle;

    fn h(i: u32) -> MonitoredItemHandle {
        MonitoredItemHandle {
            subscription_id: 1,
            monitored_item_id: i,
        }
    }

    /// An item faster than the status documents on a node of the trace puts the trace on
    /// all its nodes' items, each with its own step; the other nodes keep the snapshot.
    #[test]
    fn the_trace_feeds_its_nodes_when_one_samples_fast() {
        let (a, b, c) = (
            NodeId::new(1, "a"),
            NodeId::new(1, "b"),
            NodeId::new(1, "c"),
        );
        let trace: HashSet<NodeId> = [a.clone(), b.clone()].into_iter().collect();
        let items: Sampling = Arc::new(
            [
                (h(1), (a.clone(), 1.0)),
                (h(2), (a.clone(), 100.0)),
                (h(3), (b.clone(), -1.0)),
                (h(4), (c.clone(), 50.0)),
            ]
            .into_iter()
            .collect(),
        );
        let p = plan(&items, &trace, 1.0);
        assert!(p.trace);
        assert_eq!(
            p.steps,
            [(h(1), 1), (h(2), 100), (h(3), 10)].into_iter().collect()
        );
        assert_eq!(p.snapshot, 50.0);
        // At 10 ms the status documents do: no trace, every node's interval counts.
        let items: Sampling = Arc::new(
            [(h(1), (a.clone(), 10.0)), (h(4), (c.clone(), 2.0))]
                .into_iter()
                .collect(),
        );
        let p = plan(&items, &trace, 1.0);
        assert!(!p.trace);
        assert!(p.steps.is_empty());
        assert_eq!(p.snapshot, 2.0);
        let p = plan(&Sampling::default(), &trace, 1.0);
        assert!(!p.trace);
        assert_eq!(p.snapshot, crate::sampling::NOBODY_SAMPLES);
    }
}
