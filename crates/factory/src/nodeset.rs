//! The OPC Foundation's NodeSet of OPC 40502 (OPC UA for CNC Systems), loaded at start.
//!
//! The published file carries, besides the types, an example instance (`test`, with axes
//! X Y Z X2 Y2, channels and a spindle) organised under the Objects folder: a client would
//! take it for a machine. Only the types and what hangs below them (their instance
//! declarations, enumeration strings, encodings) are imported.

use std::collections::{HashMap, HashSet};

use opcua::nodes::{ImportedItem, NodeSet2Import, NodeSetImport, NodeSetNamespaceMapper};
use opcua::types::{NodeClass, NodeId};

/// The companion specification's namespace.
pub const CNC_NAMESPACE: &str = "http://opcfoundation.org/UA/CNC";

/// The NodeSet (OPC Foundation MIT License 1.00, in its header).
pub const CNC_NODESET: &str = include_str!("../nodesets/Opc.Ua.CNC.NodeSet.xml");

/// OPC 10000-100, Devices (DI), whose vendor nameplate the machine identification uses.
pub const DI_NAMESPACE: &str = "http://opcfoundation.org/UA/DI/";

/// OPC 40001-1, Machinery: the Machines folder and the machine identification (umati).
pub const MACHINERY_NAMESPACE: &str = "http://opcfoundation.org/UA/Machinery/";

/// The DI NodeSet (OPC Foundation MIT License 1.00, in its header).
pub const DI_NODESET: &str = include_str!("../nodesets/Opc.Ua.Di.NodeSet2.xml");

/// The Machinery NodeSet (OPC Foundation MIT License 1.00, in its header).
pub const MACHINERY_NODESET: &str = include_str!("../nodesets/Opc.Ua.Machinery.NodeSet2.xml");

/// OPC 40501-1, Machine Tools (umati): the machine tool identification.
pub const MACHINE_TOOL_NAMESPACE: &str = "http://opcfoundation.org/UA/MachineTool/";

/// `MachineToolIdentificationType` in the MachineTool namespace.
pub const MACHINE_TOOL_IDENTIFICATION_TYPE: u32 = 11;

/// OPC 10000-200, Industrial Automation (IA), which MachineTool requires.
pub const IA_NODESET: &str = include_str!("../nodesets/Opc.Ua.IA.NodeSet2.xml");

/// OPC 10031-4, ISA-95 job control 2.0, which Machinery Jobs requires.
pub const ISA95_JOB_CONTROL_NODESET: &str =
    include_str!("../nodesets/opc.ua.isa95-jobcontrol.nodeset2.xml");

/// OPC 40001-3, Machinery Job Management, which MachineTool requires.
pub const MACHINERY_JOBS_NODESET: &str =
    include_str!("../nodesets/Opc.Ua.Machinery.Jobs.Nodeset2.xml");

/// The MachineTool NodeSet (types only; OPC Foundation MIT License 1.00, in its header).
pub const MACHINE_TOOL_NODESET: &str = include_str!("../nodesets/Opc.Ua.MachineTool.NodeSet2.xml");

/// The DI, Machinery, IA, ISA-95 job control, Machinery Jobs and MachineTool NodeSets, in
/// the order they depend on each other.
pub fn identification_imports() -> anyhow::Result<Vec<Box<dyn NodeSetImport>>> {
    let load = |name: &str, xml: &str| {
        NodeSet2Import::new_str("en", xml, Vec::new())
            .map_err(|e| anyhow::anyhow!("the {name} NodeSet: {e}"))
    };
    Ok(vec![
        Box::new(load("DI", DI_NODESET)?),
        Box::new(load("Machinery", MACHINERY_NODESET)?),
        Box::new(load("IA", IA_NODESET)?),
        Box::new(load("ISA-95 job control", ISA95_JOB_CONTROL_NODESET)?),
        Box::new(load("Machinery Jobs", MACHINERY_JOBS_NODESET)?),
        Box::new(load("MachineTool", MACHINE_TOOL_NODESET)?),
    ])
}

/// The CNC NodeSet without its example instance.
pub struct CncTypes {
    inner: NodeSet2Import,
}

impl CncTypes {
    /// Parses the committed NodeSet.
    pub fn load() -> anyhow::Result<CncTypes> {
        let inner = NodeSet2Import::new_str("en", CNC_NODESET, Vec::new())
            .map_err(|e| anyhow::anyhow!("the CNC NodeSet: {e}"))?;
        Ok(CncTypes { inner })
    }
}

fn is_type(class: NodeClass) -> bool {
    matches!(
        class,
        NodeClass::ObjectType | NodeClass::VariableType | NodeClass::DataType
    ) || class == NodeClass::ReferenceType
}

/// The items reachable from a type along hierarchical references inside the file (a
/// reference counts from whichever end lists it): the types' own nodes.
fn kept(items: &[ImportedItem]) -> HashSet<NodeId> {
    let class: HashMap<&NodeId, NodeClass> = items
        .iter()
        .map(|i| (i.node.as_node().node_id(), i.node.node_class()))
        .collect();
    let mut below: HashMap<&NodeId, Vec<&NodeId>> = HashMap::new();
    for item in items {
        let id = item.node.as_node().node_id();
        for r in &item.references {
            let (from, to) = if r.is_forward {
                (id, &r.target_id)
            } else {
                (&r.target_id, id)
            };
            below.entry(from).or_default().push(to);
        }
    }
    let mut keep: HashSet<NodeId> = HashSet::new();
    let mut stack: Vec<&NodeId> = class
        .iter()
        .filter(|(_, c)| is_type(**c))
        .map(|(id, _)| *id)
        .collect();
    while let Some(id) = stack.pop() {
        if !keep.insert(id.clone()) {
            continue;
        }
        for to in below.get(id).into_iter().flatten() {
            // Into the file's instances only: a subtype is kept on its own, and
            // HasTypeDefinition, modelling rules and GeneratesEvent point at types.
            if class.get(to).is_some_and(|c| !is_type(*c)) {
                stack.push(to);
            }
        }
    }
    keep
}

impl NodeSetImport for CncTypes {
    fn register_namespaces(&self, namespaces: &mut NodeSetNamespaceMapper) {
        self.inner.register_namespaces(namespaces)
    }

    fn get_own_namespaces(&self) -> Vec<String> {
        self.inner.get_own_namespaces()
    }

    fn load<'a>(
        &'a self,
        namespaces: &'a NodeSetNamespaceMapper,
    ) -> Box<dyn Iterator<Item = ImportedItem> + 'a> {
        let items: Vec<ImportedItem> = self.inner.load(namespaces).collect();
        let keep = kept(&items);
        Box::new(
            items
                .into_iter()
                .filter(move |i| keep.contains(i.node.as_node().node_id())),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use opcua::types::NamespaceMap;

    /// The numeric node ids of the file, by whether they sit under the example instance
    /// `test` (ns=1;i=5008) or under a type, read from the XML's ParentNodeId attributes.
    fn ids_under(xml: &str, root: &str) -> Vec<u32> {
        let mut parents: Vec<(String, String)> = Vec::new();
        for node in xml.split("<UA").skip(1) {
            let attr = |a: &str| {
                let i = node.find(&format!(" {a}=\""))? + a.len() + 3;
                Some(node[i..i + node[i..].find('"')?].to_string())
            };
            if let (Some(id), Some(parent)) = (attr("NodeId"), attr("ParentNodeId")) {
                parents.push((id, parent));
            }
        }
        let mut under = vec![root.to_string()];
        loop {
            let before = under.len();
            for (id, parent) in &parents {
                if under.contains(parent) && !under.contains(id) {
                    under.push(id.clone());
                }
            }
            if under.len() == before {
                break;
            }
        }
        under
            .iter()
            .filter_map(|id| id.strip_prefix("ns=1;i=")?.parse().ok())
            .collect()
    }

    #[test]
    fn the_types_are_imported_and_the_example_machine_is_not() {
        let types = CncTypes::load().unwrap();
        let mut map = NamespaceMap::new();
        let mut mapper = NodeSetNamespaceMapper::new(&mut map);
        types.register_namespaces(&mut mapper);
        let ids: Vec<u32> = types
            .load(&mapper)
            .filter_map(|i| match &i.node.as_node().node_id().identifier {
                opcua::types::Identifier::Numeric(n) => Some(*n),
                _ => None,
            })
            .collect();
        // The example's objects (the machine `test`, its lists, axes X Y Z X2 Y2, channels,
        // spindle Q, as the XML has them without a parent) and what hangs below them.
        let objects = [
            5004, 5005, 5006, 5008, 5011, 5012, 5013, 5014, 5015, 5020, 5021, 5022, 5023, 5024,
            5025, 5032,
        ];
        let example: Vec<u32> = objects
            .iter()
            .flat_map(|o| ids_under(CNC_NODESET, &format!("ns=1;i={o}")))
            .collect();
        assert!(
            example.len() > 100,
            "the example is large: {}",
            example.len()
        );
        assert!(
            ids.iter().all(|i| !example.contains(i)),
            "no node of the example"
        );
        // Every type, and every instance declaration of CncChannelType and CncAlarmType.
        for t in [1001, 1002, 1004, 1005, 1006, 1007, 1011, 2001, 3001, 3007] {
            assert!(ids.contains(&t), "type {t}");
        }
        for root in ["ns=1;i=1002", "ns=1;i=1006", "ns=1;i=1004"] {
            for d in ids_under(CNC_NODESET, root) {
                assert!(ids.contains(&d), "{d} under {root}");
            }
        }
    }
}
