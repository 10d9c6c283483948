//! Problems of a graph file, each with its place: `file:line:column: node 'id', 'item': …`.

use std::fmt;
use std::path::{Path, PathBuf};

use super::{GraphError, Subject};
use crate::document::SourceMap;

/// One located problem.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Diagnostic {
    /// The node concerned, if any.
    pub node: Option<String>,
    /// The port, parameter or graph input concerned, if any.
    pub item: Option<String>,
    /// 1-based (line, column) in the graph file, when known.
    pub location: Option<(usize, usize)>,
    /// What is wrong and, where possible, how to fix it.
    pub message: String,
}

impl Diagnostic {
    /// `error` with its place in the file `source` maps.
    pub fn locate(error: &GraphError, source: &SourceMap) -> Diagnostic {
        let (node, item, location) = match error.subject() {
            Subject::Graph => (None, None, None),
            Subject::Node(id) => {
                let location = source.node(id.as_str());
                (Some(id.as_str().to_string()), None, location)
            }
            Subject::Port(port) => {
                let location = source.edge(&port.text()).or_else(|| source.node(port.node.as_str()));
                (Some(port.node.as_str().to_string()), Some(port.port.clone()), location)
            }
            Subject::Param(path) => {
                let location = source.param(path.node.as_str(), &path.param);
                (Some(path.node.as_str().to_string()), Some(path.param.clone()), location)
            }
            Subject::Endpoint(text) => (None, None, source.edge(&text)),
            Subject::Input(name) => {
                let location = source.input(&name);
                (None, Some(name), location)
            }
        };
        Diagnostic { node, item, location, message: error.to_string() }
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some((l, c)) = self.location {
            write!(f, "{l}:{c}: ")?;
        }
        let shown = |s: &str| s.escape_debug().to_string();
        match (&self.node, &self.item) {
            (Some(n), Some(i)) => write!(f, "node '{}', '{}': ", shown(n), shown(i))?,
            (Some(n), None) => write!(f, "node '{}': ", shown(n))?,
            (None, Some(i)) => write!(f, "'{}': ", shown(i))?,
            (None, None) => {}
        }
        f.write_str(&self.message)
    }
}

/// All problems of one graph file.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub struct GraphErrors {
    /// The graph file.
    pub path: PathBuf,
    /// Every problem found, in file order.
    pub diagnostics: Vec<Diagnostic>,
}

impl fmt::Display for GraphErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.diagnostics.len();
        writeln!(f, "{}: {n} problem{}", self.path.display(), if n == 1 { "" } else { "s" })?;
        for d in &self.diagnostics {
            writeln!(f, "{}:{d}", self.path.display())?;
        }
        Ok(())
    }
}

/// `errors` of the file at `path`, located and in file order.
pub fn located(path: &Path, source: &SourceMap, errors: Vec<GraphError>) -> GraphErrors {
    let mut diagnostics: Vec<Diagnostic> = errors.iter().map(|e| Diagnostic::locate(e, source)).collect();
    diagnostics.sort_by(|a, b| a.location.cmp(&b.location).then_with(|| a.message.cmp(&b.message)));
    GraphErrors { path: path.to_path_buf(), diagnostics }
}
