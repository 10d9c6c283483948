//! Reports: a node's or kernel's structured account of what it decided (chosen parameters,
//! measured errors). Plain JSON data, so kernels can build them without the node contract.

/// A node's structured account of what it decided (chosen parameters, measured errors):
/// shown by `kg run --json` and the editor, compared by `kg test`.
pub type Report = serde_json::Map<String, serde_json::Value>;

/// A report from a `json!` object (anything else becomes an empty report).
pub fn into_report(value: serde_json::Value) -> Report {
    match value {
        serde_json::Value::Object(map) => map,
        _ => Report::new(),
    }
}
