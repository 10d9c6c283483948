//! Node parameters: typed declarations with defaults, ranges, units and docs, and the
//! untyped values graph files carry.

use std::marker::PhantomData;

use serde::{Deserialize, Serialize};

use crate::model::choice::{Choice, is_one_of, not_one_of};

/// A parameter value as written in a graph file or given with `--set`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ParamValue {
    /// `true` / `false`.
    Bool(bool),
    /// A whole number.
    Int(i64),
    /// A real number.
    Float(f64),
    /// Text: names, choices, paths.
    Text(String),
}

impl ParamValue {
    /// The number this value holds, if it is one.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            ParamValue::Int(i) => Some(*i as f64),
            ParamValue::Float(x) => Some(*x),
            _ => None,
        }
    }
}

impl std::fmt::Display for ParamValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ParamValue::Bool(b) => write!(f, "{b}"),
            ParamValue::Int(i) => write!(f, "{i}"),
            ParamValue::Float(x) => write!(f, "{x}"),
            ParamValue::Text(s) => write!(f, "{s:?}"),
        }
    }
}

/// What values a parameter takes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ParamKind {
    /// A real number in `[min, max]`; `default: None` means "unset" (e.g. auto-detect).
    Float {
        /// Value when the graph does not set it.
        default: Option<f64>,
        /// Inclusive lower bound.
        min: f64,
        /// Inclusive upper bound.
        max: f64,
        /// Unit shown to users (`"s"`, `"m"`, `"fps"`, `""`).
        unit: &'static str,
    },
    /// A whole number in `[min, max]`; `default: None` means "unset".
    Int {
        /// Value when the graph does not set it.
        default: Option<i64>,
        /// Inclusive lower bound.
        min: i64,
        /// Inclusive upper bound.
        max: i64,
    },
    /// One of a fixed set of names.
    Choice {
        /// Allowed names.
        choices: &'static [&'static str],
        /// Value when the graph does not set it.
        default: &'static str,
    },
    /// Free text (a joint name, a selection): the node parses it and names this
    /// parameter in its error when it cannot.
    Text {
        /// Value when the graph does not set it.
        default: &'static str,
    },
    /// A file to read; relative paths resolve against the graph file's folder.
    InputPath {
        /// Accepted extensions, lowercase without the dot.
        extensions: &'static [&'static str],
        /// Whether the node refuses to run without it.
        required: bool,
    },
    /// A folder to read files from, sub-folders included; relative paths resolve against
    /// the graph file's folder. The engine fingerprints the files under it that have one of
    /// `extensions`, so adding, removing or editing one re-runs the node.
    InputFolder {
        /// Extensions of the files the node reads there, lowercase without the dot.
        extensions: &'static [&'static str],
        /// Value when the graph does not set it.
        default: &'static str,
    },
    /// A file to write, relative to the run's output folder and never leaving it.
    OutputPath {
        /// Required extension, lowercase without the dot.
        extension: &'static str,
        /// Value when the graph does not set it.
        default: &'static str,
    },
}

/// A parameter's schema entry.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ParamSpec {
    /// Stable name, persisted in graph files.
    pub name: &'static str,
    /// Tooltip text for animators.
    pub doc: &'static str,
    /// Accepted values.
    #[serde(flatten)]
    pub kind: ParamKind,
}

impl ParamSpec {
    /// The default value, if the parameter has one.
    pub fn default_value(&self) -> Option<ParamValue> {
        match self.kind {
            ParamKind::Float { default, .. } => default.map(ParamValue::Float),
            ParamKind::Int { default, .. } => default.map(ParamValue::Int),
            ParamKind::Choice { default, .. }
            | ParamKind::OutputPath { default, .. }
            | ParamKind::InputFolder { default, .. }
            | ParamKind::Text { default } => Some(ParamValue::Text(default.to_string())),
            ParamKind::InputPath { .. } => None,
        }
    }

    /// Checks `value` against this spec and returns it in canonical form (an integer
    /// given for a real becomes a real). The error explains what is accepted.
    pub fn check(&self, value: &ParamValue) -> Result<ParamValue, String> {
        match (self.kind, value) {
            (ParamKind::Float { min, max, unit, .. }, ParamValue::Float(_) | ParamValue::Int(_)) => {
                let x = value.as_f64().unwrap_or(f64::NAN);
                if !x.is_finite() || x < min || x > max {
                    return Err(format!("{x} is outside {min}..={max} {unit}"));
                }
                Ok(ParamValue::Float(x))
            }
            (ParamKind::Int { min, max, .. }, ParamValue::Int(i)) => {
                if *i < min || *i > max {
                    return Err(format!("{i} is outside {min}..={max}"));
                }
                Ok(ParamValue::Int(*i))
            }
            (ParamKind::Choice { choices, .. }, ParamValue::Text(s)) => {
                if choices.contains(&s.as_str()) {
                    Ok(value.clone())
                } else {
                    Err(not_one_of(s, choices))
                }
            }
            (ParamKind::Text { .. } | ParamKind::InputFolder { .. }, ParamValue::Text(_)) => Ok(value.clone()),
            (ParamKind::InputPath { extensions, .. }, ParamValue::Text(s)) => {
                if extensions.contains(&crate::formats::extension(std::path::Path::new(s)).as_str()) {
                    Ok(value.clone())
                } else {
                    Err(format!("'{s}' does not end in one of .{}", extensions.join(", .")))
                }
            }
            (ParamKind::OutputPath { extension, .. }, ParamValue::Text(s)) => {
                check_output_path(s, extension).map(|()| value.clone())
            }
            (kind, other) => Err(format!("expected {}, got {other}", kind_name(kind))),
        }
    }
}

fn kind_name(kind: ParamKind) -> &'static str {
    match kind {
        ParamKind::Float { .. } => "a number",
        ParamKind::Int { .. } => "a whole number",
        ParamKind::Choice { .. } => "a choice (text)",
        ParamKind::Text { .. } => "text",
        ParamKind::InputPath { .. } | ParamKind::InputFolder { .. } | ParamKind::OutputPath { .. } => "a path (text)",
    }
}

/// An output path must be relative, stay inside the output folder and carry `extension`.
fn check_output_path(s: &str, extension: &str) -> Result<(), String> {
    use std::path::Component;
    let path = std::path::Path::new(s);
    if s.is_empty() {
        return Err("an output path cannot be empty".into());
    }
    if path.components().any(|c| !matches!(c, Component::Normal(_) | Component::CurDir)) {
        return Err(format!("'{s}' leaves the output folder: give a relative path without '..'"));
    }
    // No file system takes these in a name; refused here, not half way through a run.
    if let Some(c) = s.chars().find(|c| c.is_control() || matches!(c, '\\' | ':' | '*' | '?' | '"' | '<' | '>' | '|')) {
        return Err(format!("'{}' holds the character {c:?}, which file names cannot carry", s.escape_debug()));
    }
    if path.components().any(|c| c.as_os_str().to_string_lossy().starts_with(".kg-")) {
        return Err(format!("'{s}': names starting with '.kg-' are kg's own (locks, temporary files)"));
    }
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case(extension)) {
        return Err(format!("'{s}' must end in .{extension}"));
    }
    Ok(())
}

/// A typed real-number parameter declaration.
pub struct FloatParam(pub ParamSpec);
/// A typed whole-number parameter declaration.
pub struct IntParam(pub ParamSpec);
/// A typed choice parameter declaration: the node reads a `T`, and the names the spec
/// offers are `T`'s own ([`Choice::NAMES`]).
pub struct ChoiceParam<T: Choice>(pub ParamSpec, PhantomData<fn() -> T>);
/// A typed free-text parameter declaration.
pub struct TextParam(pub ParamSpec);
/// A typed input-file parameter declaration.
pub struct InputPathParam(pub ParamSpec);
/// A typed input-folder parameter declaration.
pub struct InputFolderParam(pub ParamSpec);
/// A typed output-file parameter declaration.
pub struct OutputPathParam(pub ParamSpec);

impl FloatParam {
    /// Declares a real parameter with a default.
    pub const fn new(
        name: &'static str,
        doc: &'static str,
        default: f64,
        min: f64,
        max: f64,
        unit: &'static str,
    ) -> Self {
        FloatParam(ParamSpec { name, doc, kind: ParamKind::Float { default: Some(default), min, max, unit } })
    }
    /// Declares a real parameter that may stay unset.
    pub const fn optional(name: &'static str, doc: &'static str, min: f64, max: f64, unit: &'static str) -> Self {
        FloatParam(ParamSpec { name, doc, kind: ParamKind::Float { default: None, min, max, unit } })
    }
}

impl IntParam {
    /// Declares a whole-number parameter with a default.
    pub const fn new(name: &'static str, doc: &'static str, default: i64, min: i64, max: i64) -> Self {
        IntParam(ParamSpec { name, doc, kind: ParamKind::Int { default: Some(default), min, max } })
    }
    /// Declares a whole-number parameter that may stay unset.
    pub const fn optional(name: &'static str, doc: &'static str, min: i64, max: i64) -> Self {
        IntParam(ParamSpec { name, doc, kind: ParamKind::Int { default: None, min, max } })
    }
}

impl<T: Choice> ChoiceParam<T> {
    /// Declares a choice parameter offering `T`'s names. A `default` that is not one of
    /// them fails to compile where the declaration is used:
    ///
    /// ```
    /// use kinegraph_nodes::node::{ChoiceParam, OnOff, ParamSpec};
    /// const FOOT_LOCK: ChoiceParam<OnOff> = ChoiceParam::new("foot_lock", "Hold planted feet.", "on");
    /// static PARAMS: [ParamSpec; 1] = [FOOT_LOCK.0];
    /// ```
    ///
    /// ```compile_fail,E0080
    /// use kinegraph_nodes::node::{ChoiceParam, OnOff, ParamSpec};
    /// const FOOT_LOCK: ChoiceParam<OnOff> = ChoiceParam::new("foot_lock", "Hold planted feet.", "of");
    /// static PARAMS: [ParamSpec; 1] = [FOOT_LOCK.0];
    /// ```
    pub const fn new(name: &'static str, doc: &'static str, default: &'static str) -> Self {
        assert!(is_one_of(default, T::NAMES), "a choice parameter's default must be one of its choice's names");
        ChoiceParam(ParamSpec { name, doc, kind: ParamKind::Choice { choices: T::NAMES, default } }, PhantomData)
    }
}

impl TextParam {
    /// Declares a text parameter with a default.
    pub const fn new(name: &'static str, doc: &'static str, default: &'static str) -> Self {
        TextParam(ParamSpec { name, doc, kind: ParamKind::Text { default } })
    }
}

impl InputPathParam {
    /// Declares an input file parameter (required: no default).
    pub const fn new(name: &'static str, doc: &'static str, extensions: &'static [&'static str]) -> Self {
        InputPathParam(ParamSpec { name, doc, kind: ParamKind::InputPath { extensions, required: true } })
    }
    /// Declares an input file parameter that may stay unset.
    pub const fn optional(name: &'static str, doc: &'static str, extensions: &'static [&'static str]) -> Self {
        InputPathParam(ParamSpec { name, doc, kind: ParamKind::InputPath { extensions, required: false } })
    }
}

impl InputFolderParam {
    /// Declares an input folder parameter read for files with `extensions`.
    pub const fn new(
        name: &'static str,
        doc: &'static str,
        extensions: &'static [&'static str],
        default: &'static str,
    ) -> Self {
        InputFolderParam(ParamSpec { name, doc, kind: ParamKind::InputFolder { extensions, default } })
    }
}

impl OutputPathParam {
    /// Declares an output file parameter.
    pub const fn new(name: &'static str, doc: &'static str, extension: &'static str, default: &'static str) -> Self {
        OutputPathParam(ParamSpec { name, doc, kind: ParamKind::OutputPath { extension, default } })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_ranges_types_and_paths() {
        let f = FloatParam::new("t", "", 1.0, 0.0, 10.0, "s").0;
        assert_eq!(f.check(&ParamValue::Int(3)), Ok(ParamValue::Float(3.0)));
        assert!(f.check(&ParamValue::Float(11.0)).is_err());
        assert!(f.check(&ParamValue::Float(f64::NAN)).is_err());
        assert!(f.check(&ParamValue::Text("x".into())).unwrap_err().contains("expected a number"));
        let out = OutputPathParam::new("file", "", "glb", "out.glb").0;
        assert!(out.check(&ParamValue::Text("sub/a.glb".into())).is_ok());
        for bad in ["../a.glb", "/tmp/a.glb", "a.bvh", "", "sub/../../a.glb"] {
            assert!(out.check(&ParamValue::Text(bad.into())).is_err(), "{bad}");
        }
        let inp = InputPathParam::new("path", "", &["bvh", "glb"]).0;
        assert!(inp.check(&ParamValue::Text("x/Walk.BVH".into())).is_ok());
        assert!(inp.check(&ParamValue::Text("x/walk.fbx".into())).is_err());
    }

    #[test]
    fn a_choice_spec_offers_its_enums_names_and_refuses_others() {
        use crate::model::choice::OnOff;
        const SWITCH: ChoiceParam<OnOff> = ChoiceParam::new("foot_lock", "", "off");
        assert_eq!(SWITCH.0.kind, ParamKind::Choice { choices: &["on", "off"], default: "off" });
        assert_eq!(SWITCH.0.check(&ParamValue::Text("on".into())), Ok(ParamValue::Text("on".into())));
        assert_eq!(SWITCH.0.check(&ParamValue::Text("maybe".into())), Err("'maybe' is not one of on, off".into()));
    }

    #[test]
    fn untagged_values_parse_from_ron_literals() {
        let v: Vec<ParamValue> = serde_json::from_str(r#"[true, 3, 2.5, "a"]"#).unwrap();
        assert_eq!(
            v,
            vec![ParamValue::Bool(true), ParamValue::Int(3), ParamValue::Float(2.5), ParamValue::Text("a".into())]
        );
    }
}
