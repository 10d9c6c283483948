//! `kg nodes`: the node catalogue, generated from the schemas.

use kinegraph_nodes::node::{NodeSchema, ParamKind, ParamSpec, Registry};

/// Every schema, sorted by kind, as the JSON `kg nodes --json` prints.
pub fn catalogue_json(registry: &Registry) -> serde_json::Value {
    serde_json::Value::Array(registry.iter().map(|n| serde_json::to_value(n.schema()).unwrap_or_default()).collect())
}

fn param_range(p: &ParamSpec) -> String {
    match p.kind {
        ParamKind::Float { default, min, max, unit } => {
            let d = default.map(|d| format!("{d}")).unwrap_or_else(|| "unset".into());
            format!("number {min}..={max} {unit}, default {d}")
        }
        ParamKind::Int { default, min, max } => {
            let d = default.map(|d| format!("{d}")).unwrap_or_else(|| "unset".into());
            format!("whole number {min}..={max}, default {d}")
        }
        ParamKind::Choice { choices, default } => format!("one of {}, default {default}", choices.join(" | ")),
        ParamKind::InputPath { extensions, required } => {
            format!("input file (.{}), {}", extensions.join(", ."), if required { "required" } else { "optional" })
        }
        ParamKind::InputFolder { extensions, default } => {
            format!("input folder (reads .{}), default {default:?}", extensions.join(", ."))
        }
        ParamKind::Text { default } => format!("text, default {default:?}"),
        ParamKind::OutputPath { extension, default } => format!("output file (.{extension}), default {default}"),
    }
}

fn markdown(schema: &NodeSchema) -> String {
    let mut s = format!("## `{}` ({})\n\n{}\n\n", schema.kind, schema.category, schema.doc);
    let ports = |title: &str, ports: &[kinegraph_nodes::node::PortSpec], s: &mut String| {
        if !ports.is_empty() {
            s.push_str(&format!("**{title}**\n\n"));
            for p in ports {
                let req = if p.required { ", required" } else { "" };
                s.push_str(&format!("- `{}` ({}{req}): {}\n", p.name, p.ty.name(), p.doc));
            }
            s.push('\n');
        }
    };
    ports("Inputs", schema.inputs, &mut s);
    ports("Outputs", schema.outputs, &mut s);
    if !schema.params.is_empty() {
        s.push_str("**Parameters**\n\n");
        for p in schema.params {
            s.push_str(&format!("- `{}` ({}): {}\n", p.name, param_range(p), p.doc));
        }
        s.push('\n');
    }
    s
}

pub(super) fn nodes_command(json: bool, as_markdown: bool) -> u8 {
    let registry = kinegraph_nodes::builtin::registry();
    if json {
        outln!("{}", serde_json::to_string_pretty(&catalogue_json(&registry)).unwrap_or_default());
    } else if as_markdown {
        outln!("# kinegraph node catalogue\n");
        for node in registry.iter() {
            out!("{}", markdown(node.schema()));
        }
    } else {
        for node in registry.iter() {
            let s = node.schema();
            let ins: Vec<String> = s.inputs.iter().map(|p| format!("{}:{}", p.name, p.ty.name())).collect();
            let outs: Vec<String> = s.outputs.iter().map(|p| format!("{}:{}", p.name, p.ty.name())).collect();
            outln!("{:<16} ({}) -> ({})  {}", s.kind, ins.join(", "), outs.join(", "), s.doc);
            for p in s.params {
                outln!("    {:<16} {}", p.name, param_range(p));
            }
        }
    }
    0
}
