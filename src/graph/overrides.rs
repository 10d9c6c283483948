//! Settings from outside the file — `kg run --set`, a farm task's input bindings, a
//! parameter sweep — as one [`Overrides`] value applied in one place.

use std::path::Path;
use std::str::FromStr;

use kinegraph_nodes::node::{ParamKind, ParamValue, Registry};

use super::{Graph, GraphError, ParamPath, rules};

/// One `NAME=VALUE`: a graph input name or `node.param`, and the value's text.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    /// Graph input name or `node.param`.
    pub name: String,
    /// The raw value text.
    pub value: String,
}

impl FromStr for Setting {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (name, value) = s.split_once('=').ok_or_else(|| format!("'{s}' is not NAME=VALUE"))?;
        if name.is_empty() {
            return Err(format!("'{s}' has an empty name"));
        }
        Ok(Setting { name: name.to_string(), value: value.to_string() })
    }
}

/// Settings applied in order over a graph's own parameter values.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overrides(pub Vec<Setting>);

impl Overrides {
    /// Applies every setting: each name resolved once ([`Graph::resolve`]), each value read
    /// by the kind of parameter it lands in and checked against its schema. Input-file
    /// values given as relative paths are taken relative to the current folder (where the
    /// user typed them), not the graph's. The first failure is returned, naming the setting.
    pub fn apply(&self, graph: &mut Graph, registry: &Registry) -> Result<(), OverrideError> {
        for setting in &self.0 {
            let fail = |error| OverrideError { setting: setting.name.clone(), error: Box::new(error) };
            let path = graph.resolve(&setting.name).map_err(fail)?;
            let value = if is_input_file(graph, registry, &path).map_err(fail)? {
                let absolute = std::path::absolute(Path::new(&setting.value))
                    .unwrap_or_else(|_| Path::new(&setting.value).to_path_buf());
                ParamValue::Text(absolute.to_string_lossy().into_owned())
            } else {
                parse_value(&setting.value)
            };
            graph.set_param(registry, &path, &value).map_err(fail)?;
        }
        Ok(())
    }
}

/// A setting that could not be applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{setting}: {error}")]
pub struct OverrideError {
    /// The setting's name, as given.
    pub setting: String,
    /// Why.
    #[source]
    pub error: Box<GraphError>,
}

/// True when `path` is a parameter that names a file or folder to read.
pub fn is_input_file(graph: &Graph, registry: &Registry, path: &ParamPath) -> Result<bool, GraphError> {
    if rules::is_subgraph(graph, &path.node) {
        return Ok(path.param == crate::document::SUBGRAPH_FILE_PARAM);
    }
    Ok(matches!(
        rules::param_spec(graph, registry, path)?.kind,
        ParamKind::InputPath { .. } | ParamKind::InputFolder { .. }
    ))
}

/// A value's text: a RON number, bool or quoted string, else the raw text.
fn parse_value(text: &str) -> ParamValue {
    ron::from_str::<ParamValue>(text).unwrap_or_else(|_| ParamValue::Text(text.to_string()))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn demo() -> Graph {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
        Graph::from_doc(&crate::document::load_file(&path).unwrap().doc).unwrap()
    }

    fn set(name: &str, value: &str) -> Overrides {
        Overrides(vec![Setting { name: name.into(), value: value.into() }])
    }

    #[test]
    fn names_values_and_files() {
        let registry = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        set("resample.fps", "30").apply(&mut graph, &registry).unwrap();
        assert_eq!(graph.node("resample").unwrap().params["fps"], ParamValue::Float(30.0));
        set("clip_path", "walk.bvh").apply(&mut graph, &registry).unwrap();
        let ParamValue::Text(path) = &graph.node("clip").unwrap().params["path"] else { panic!() };
        assert_eq!(Path::new(path), std::env::current_dir().unwrap().join("walk.bvh"));
        let err = set("resample.fps", "-5").apply(&mut graph, &registry).unwrap_err();
        assert!(matches!(*err.error, GraphError::BadValue { .. }), "{err}");
        let err = set("nobody.fps", "5").apply(&mut graph, &registry).unwrap_err();
        assert!(matches!(*err.error, GraphError::UnknownNode { .. }), "{err}");
        let err = set("fps", "5").apply(&mut graph, &registry).unwrap_err();
        assert_eq!(err.to_string(), "fps: 'fps' is neither a graph input (clip_path, mesh_path) nor node.param");
    }
}
