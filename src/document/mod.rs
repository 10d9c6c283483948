//! The graph file: a versioned RON document.
//!
//! ```ron
//! (
//!     format: "kinegraph.graph",
//!     version: 2,
//!     description: "Walk cycle to GLB",
//!     inputs: { "clip_path": "load.path" },
//!     nodes: {
//!         "load": (kind: "clip.load", params: { "path": "../assets/walk.bvh" }),
//!         "export": (kind: "export.glb", params: { "file": "walk.glb" }),
//!     },
//!     edges: [ (from: "load.clip", to: "export.clip") ],
//!     layout: { "load": (0.0, 0.0), "export": (240.0, 0.0) },
//! )
//! ```
//!
//! `format` and `version` are checked before anything else; older versions are migrated
//! (see [`v1`]), newer ones refused. Maps are sorted and edges ordered on save, so saving
//! twice gives identical bytes and diffs stay small.

mod locate;
pub mod v1;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use kinegraph_nodes::node::ParamValue;
use serde::{Deserialize, Serialize};

pub use locate::SourceMap;

/// The `format` string every graph file carries.
pub const FORMAT: &str = "kinegraph.graph";
/// The newest version this build reads. Files are written at the oldest version that can
/// hold them ([`written_version`]): a graph without subgraphs stays version 2, so older
/// builds keep reading it; one with subgraphs is version 3, which they refuse by version.
pub const CURRENT_VERSION: u32 = 3;

/// The node kind of a subgraph node (version 3): its `file` parameter names the graph file.
pub const SUBGRAPH_KIND: &str = "graph.subgraph";

/// The parameter of a subgraph node that names its graph file.
pub const SUBGRAPH_FILE_PARAM: &str = "file";

/// A graph file (current version).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphDoc {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`CURRENT_VERSION`] once loaded.
    pub version: u32,
    /// Free text shown in catalogues and the editor.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// Graph inputs: promoted parameters, by public name, as `"node.param"`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty", deserialize_with = "unique_input_names")]
    pub inputs: BTreeMap<String, String>,
    /// Nodes by id (a repeated id is a parse error, not a silent overwrite).
    #[serde(deserialize_with = "unique_node_ids")]
    pub nodes: BTreeMap<String, NodeDoc>,
    /// Connections.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub edges: Vec<EdgeDoc>,
    /// Editor positions of nodes, by id (canvas units).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty", deserialize_with = "unique_layout_ids")]
    pub layout: BTreeMap<String, (f32, f32)>,
    /// The ports this graph shows when used as a subgraph (version 3).
    #[serde(default, skip_serializing_if = "PortsDoc::is_empty")]
    pub ports: PortsDoc,
}

/// A graph's ports as a subgraph: each public input feeds one or more inner inputs, each
/// public output is one inner output.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PortsDoc {
    /// Public input name → the inner `"node.input"`s it feeds.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty", deserialize_with = "unique_port_names")]
    pub inputs: BTreeMap<String, Vec<String>>,
    /// Public output name → the inner `"node.output"` it gives.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty", deserialize_with = "unique_port_names")]
    pub outputs: BTreeMap<String, String>,
}

impl PortsDoc {
    /// True when the graph shows no ports.
    pub fn is_empty(&self) -> bool {
        self.inputs.is_empty() && self.outputs.is_empty()
    }
}

/// The version a document is written at: 3 when it uses subgraphs, shows ports or bypasses
/// a node, else 2.
pub fn written_version(doc: &GraphDoc) -> u32 {
    let new = !doc.ports.is_empty() || doc.nodes.values().any(|n| n.kind == SUBGRAPH_KIND || n.bypass);
    if new { 3 } else { 2 }
}

/// One node of a graph file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeDoc {
    /// Node kind, e.g. `"clip.load"`.
    pub kind: String,
    /// Parameter values by name; unset ones take the schema default.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty", deserialize_with = "unique_param_names")]
    pub params: BTreeMap<String, ParamValue>,
    /// Bypassed (version 3): the node does not run and each output passes on an input of
    /// its type, so a step can be switched off without rewiring the graph.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub bypass: bool,
}

/// A connection `"node.port" → "node.port"`.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EdgeDoc {
    /// Source, `"node.output"`.
    pub from: String,
    /// Destination, `"node.input"`.
    pub to: String,
}

/// Deserialises a map, refusing repeated keys (serde's default keeps the last silently);
/// `what` names a key in the message ("node id").
fn unique_keys<'de, D, V>(deserializer: D, what: &'static str) -> Result<BTreeMap<String, V>, D::Error>
where
    D: serde::Deserializer<'de>,
    V: Deserialize<'de>,
{
    struct Visitor<V>(&'static str, std::marker::PhantomData<V>);
    impl<'de, V: Deserialize<'de>> serde::de::Visitor<'de> for Visitor<V> {
        type Value = BTreeMap<String, V>;
        fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "a map by {}", self.0)
        }
        fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
            let mut out = BTreeMap::new();
            while let Some((key, value)) = map.next_entry::<String, V>()? {
                if out.contains_key(&key) {
                    let shown: String = key.chars().take(80).collect::<String>().escape_debug().to_string();
                    return Err(serde::de::Error::custom(format!(
                        "duplicate {} '{shown}': each may appear once (keep one of the two)",
                        self.0
                    )));
                }
                out.insert(key, value);
            }
            Ok(out)
        }
    }
    deserializer.deserialize_map(Visitor(what, std::marker::PhantomData))
}

fn unique_node_ids<'de, D: serde::Deserializer<'de>>(d: D) -> Result<BTreeMap<String, NodeDoc>, D::Error> {
    unique_keys(d, "node id")
}

fn unique_input_names<'de, D: serde::Deserializer<'de>>(d: D) -> Result<BTreeMap<String, String>, D::Error> {
    unique_keys(d, "graph input")
}

pub(crate) fn unique_param_names<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<BTreeMap<String, ParamValue>, D::Error> {
    unique_keys(d, "parameter")
}

fn unique_port_names<'de, D: serde::Deserializer<'de>, V: Deserialize<'de>>(
    d: D,
) -> Result<BTreeMap<String, V>, D::Error> {
    unique_keys(d, "port")
}

fn unique_layout_ids<'de, D: serde::Deserializer<'de>>(d: D) -> Result<BTreeMap<String, (f32, f32)>, D::Error> {
    unique_keys(d, "layout entry")
}

/// Why a graph file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum DocumentError {
    /// The file could not be read or written.
    #[error("{}: {message}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
    /// RON syntax or shape error at a position.
    #[error("{}:{line}:{column}: {message}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// Not a graph file, or a version this build cannot read.
    #[error("{}: {message}", path.display())]
    Version {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// The two fields read before anything else; absent ones stay empty / zero.
#[derive(Deserialize)]
struct Header {
    #[serde(default)]
    format: String,
    #[serde(default)]
    version: u32,
}

/// A loaded graph with where it came from.
#[derive(Clone, Debug)]
pub struct LoadedGraph {
    /// The document, migrated to the current version.
    pub doc: GraphDoc,
    /// Line lookups into the original text (empty for migrated files).
    pub source: SourceMap,
    /// The file it was read from.
    pub path: PathBuf,
    /// The version found in the file before migration.
    pub file_version: u32,
}

impl LoadedGraph {
    /// Folder that relative input paths resolve against.
    pub fn base_dir(&self) -> PathBuf {
        self.path.parent().map(Path::to_path_buf).unwrap_or_default()
    }
}

/// Reads a graph file from disk.
pub fn load_file(path: &Path) -> Result<LoadedGraph, DocumentError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| DocumentError::Io { path: path.to_path_buf(), message: e.to_string() })?;
    parse(&text, path)
}

fn parse_error(path: &Path, e: ron::error::SpannedError) -> DocumentError {
    DocumentError::Parse {
        path: path.to_path_buf(),
        line: e.span.start.line,
        column: e.span.start.col,
        message: readable(&e.code),
    }
}

/// The parser's message in the words of a graph file: no serde internals, no value echoed
/// past a screenful.
fn readable(code: &ron::Error) -> String {
    let text = match code {
        ron::Error::ExceededRecursionLimit => "brackets nest too deeply for a graph file".to_string(),
        other if other.to_string().contains("untagged enum ParamValue") => {
            "a parameter value must be a number, true/false or \"text\"".to_string()
        }
        other => other.to_string(),
    };
    shorten(&text, 200)
}

/// `text` cut to `max` characters, saying how much was left out.
pub fn shorten(text: &str, max: usize) -> String {
    let count = text.chars().count();
    if count <= max {
        return text.to_string();
    }
    let kept: String = text.chars().take(max).collect();
    format!("{kept}… ({} more characters)", count - max)
}

/// Parses graph text; `path` names the file in errors and anchors relative paths.
pub fn parse(text: &str, path: &Path) -> Result<LoadedGraph, DocumentError> {
    let header: Header = ron::from_str(text).map_err(|e| parse_error(path, e))?;
    let version_error = |message: String| DocumentError::Version { path: path.to_path_buf(), message };
    match header.format.as_str() {
        FORMAT => {}
        "" => {
            return Err(version_error(format!(
                "no 'format' field: not a kinegraph graph (expected format: \"{FORMAT}\")"
            )));
        }
        other => return Err(version_error(format!("format is '{other}', expected '{FORMAT}'"))),
    }
    let file_version = header.version;
    if file_version == 0 {
        return Err(version_error("no 'version' field (or version 0)".into()));
    }
    let doc = match file_version {
        2 | 3 => ron::from_str::<GraphDoc>(text).map_err(|e| parse_error(path, e))?,
        1 => v1::migrate(ron::from_str::<v1::GraphDocV1>(text).map_err(|e| parse_error(path, e))?)
            .map_err(|message| version_error(format!("cannot migrate this version-1 graph: {message}")))?,
        v if v > CURRENT_VERSION => {
            return Err(version_error(format!(
                "graph version {v} is newer than this kinegraph understands (up to {CURRENT_VERSION}): upgrade kinegraph"
            )));
        }
        v => return Err(version_error(format!("graph version {v} is not a known version (1..={CURRENT_VERSION})"))),
    };
    // Version-1 files index too: their keys sit elsewhere (lookups find none), but comments count.
    let source = SourceMap::new(text);
    Ok(LoadedGraph { doc, source, path: path.to_path_buf(), file_version })
}

/// Serialises a graph deterministically (sorted maps, sorted edges).
pub fn to_string(doc: &GraphDoc) -> String {
    let mut doc = doc.clone();
    doc.edges.sort();
    doc.edges.dedup();
    doc.format = FORMAT.to_string();
    doc.version = written_version(&doc);
    let config = ron::ser::PrettyConfig::new().indentor("    ").struct_names(false);
    let mut text =
        ron::ser::to_string_pretty(&doc, config).unwrap_or_else(|e| format!("// serialisation failed: {e}\n"));
    text.push('\n');
    text
}

/// Writes a graph file atomically.
pub fn save_file(doc: &GraphDoc, path: &Path) -> Result<(), DocumentError> {
    kinegraph_nodes::formats::atomic::write_atomic(path, to_string(doc).as_bytes())
        .map_err(|e| DocumentError::Io { path: path.to_path_buf(), message: e.message })
}

impl GraphDoc {
    /// An empty current-version document.
    pub fn new() -> Self {
        GraphDoc {
            format: FORMAT.to_string(),
            version: CURRENT_VERSION,
            description: String::new(),
            inputs: BTreeMap::new(),
            nodes: BTreeMap::new(),
            edges: Vec::new(),
            layout: BTreeMap::new(),
            ports: PortsDoc::default(),
        }
    }
}

impl Default for GraphDoc {
    fn default() -> Self {
        Self::new()
    }
}
