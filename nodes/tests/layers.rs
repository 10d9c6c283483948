//! The layers of `nodes/src` stay acyclic: a module imports only from its own layer or
//! lower ones, and a node family never imports another family.
//!
//! Layers, lowest first (see `kinegraph_nodes` crate docs and DESIGN.md §1b):
//!
//! | rank | modules            | holds                                                     |
//! |------|--------------------|-----------------------------------------------------------|
//! | 0    | `math`, `corpus`, `cancel` | maths helpers; the shared data corpus; stop requests (std only) |
//! | 1    | `model`            | skeletons, clips, meshes, reports, name hints             |
//! | 2    | `formats`          | BVH, glTF, OBJ, bone-map files                            |
//! | 3    | `kernels`          | motion operations several node families share             |
//! | 4    | `node`             | the node contract (Node, ports, params, Value, Registry)  |
//! | 5    | `builtin`          | the node families, one module each, and their registry    |
//!
//! The check is a small text scan: every `crate::…`, `super::…` and `self::…` path in the
//! code of every `.rs` file under `nodes/src` (comments and string literals blanked out;
//! `use` lines, brace groups and paths written inline alike), resolved against the module
//! the path is written in (inline `mod tests { … }` included).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Top-level modules of `nodes/src` and their rank. A new top-level module must be added
/// here, or the test fails.
const LAYERS: [(&str, u8); 8] = [
    ("math", 0),
    ("corpus", 0),
    ("cancel", 0),
    ("model", 1),
    ("formats", 2),
    ("kernels", 3),
    ("node", 4),
    ("builtin", 5),
];

/// Rank of the crate root (`lib.rs`): above everything, importable by nothing.
const ROOT_RANK: u8 = 6;

/// One broken rule.
#[derive(Debug, Clone, PartialEq)]
struct Violation {
    /// File, relative to `nodes/src`.
    file: String,
    /// 1-based line of the offending path.
    line: usize,
    /// What is wrong.
    message: String,
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "nodes/src/{}:{}: {}", self.file, self.line, self.message)
    }
}

/// The module path of a file relative to `nodes/src`: `builtin/ik/map.rs` → `[builtin, ik,
/// map]`, `kernels/mod.rs` → `[kernels]`, `lib.rs` → `[]`.
fn module_of(relative: &str) -> Vec<String> {
    let relative = relative.trim_end_matches(".rs");
    let mut parts: Vec<String> = relative.split('/').map(str::to_owned).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        parts.pop();
    }
    parts
}

/// `text` with comments, string literals and char literals replaced by spaces (newlines
/// kept, so byte offsets and line numbers are unchanged).
fn blank_non_code(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = b.to_vec();
    let blank = |out: &mut Vec<u8>, from: usize, to: usize| {
        for c in &mut out[from..to.min(b.len())] {
            if *c != b'\n' {
                *c = b' ';
            }
        }
    };
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'/' if b.get(i + 1) == Some(&b'/') => {
                let end = b[i..].iter().position(|&c| c == b'\n').map_or(b.len(), |p| i + p);
                blank(&mut out, i, end);
                i = end;
            }
            b'/' if b.get(i + 1) == Some(&b'*') => {
                let (mut depth, mut j) = (1, i + 2);
                while j < b.len() && depth > 0 {
                    if b[j] == b'/' && b.get(j + 1) == Some(&b'*') {
                        depth += 1;
                        j += 2;
                    } else if b[j] == b'*' && b.get(j + 1) == Some(&b'/') {
                        depth -= 1;
                        j += 2;
                    } else {
                        j += 1;
                    }
                }
                blank(&mut out, i, j);
                i = j;
            }
            b'r' if (b.get(i + 1) == Some(&b'"') || b.get(i + 1) == Some(&b'#'))
                && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')) =>
            {
                // Raw string r"…" or r#"…"#.
                let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
                if b.get(i + 1 + hashes) != Some(&b'"') {
                    i += 1;
                    continue;
                }
                let close: Vec<u8> = std::iter::once(b'"').chain(std::iter::repeat_n(b'#', hashes)).collect();
                let start = i + 2 + hashes;
                let end = b[start..]
                    .windows(close.len())
                    .position(|w| w == close.as_slice())
                    .map_or(b.len(), |p| start + p + close.len());
                blank(&mut out, i, end);
                i = end;
            }
            b'"' => {
                let mut j = i + 1;
                while j < b.len() && b[j] != b'"' {
                    j += if b[j] == b'\\' { 2 } else { 1 };
                }
                blank(&mut out, i, j + 1);
                i = j + 1;
            }
            b'\'' => {
                // A char literal ('x', '\n', '\u{..}'), not a lifetime ('a).
                let end = if b.get(i + 1) == Some(&b'\\') {
                    b[i + 2..].iter().position(|&c| c == b'\'').map(|p| i + 2 + p + 1)
                } else if b.get(i + 2) == Some(&b'\'') {
                    Some(i + 3)
                } else {
                    // Multi-byte UTF-8 char literal, e.g. '→'.
                    let len = text[i + 1..].chars().next().map_or(1, char::len_utf8);
                    (b.get(i + 1 + len) == Some(&b'\'')).then_some(i + 2 + len)
                };
                match end {
                    Some(end) => {
                        blank(&mut out, i, end);
                        i = end;
                    }
                    None => i += 1,
                }
            }
            _ => i += 1,
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// A token of blanked code: an identifier, `::`, or one punctuation byte, with its line.
#[derive(Debug, Clone, PartialEq)]
struct Token {
    text: String,
    line: usize,
}

fn tokenize(code: &str) -> Vec<Token> {
    let b = code.as_bytes();
    let (mut tokens, mut line, mut i) = (Vec::new(), 1, 0);
    while i < b.len() {
        let c = b[i];
        if c == b'\n' {
            line += 1;
            i += 1;
        } else if c.is_ascii_whitespace() {
            i += 1;
        } else if c.is_ascii_alphanumeric() || c == b'_' || c >= 0x80 {
            let start = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] >= 0x80) {
                i += 1;
            }
            tokens.push(Token { text: code[start..i].to_owned(), line });
        } else if c == b':' && b.get(i + 1) == Some(&b':') {
            tokens.push(Token { text: "::".into(), line });
            i += 2;
        } else {
            tokens.push(Token { text: (c as char).to_string(), line });
            i += 1;
        }
    }
    tokens
}

/// The paths a path expression starting at `tokens[i]` (just after a leading `::`) names,
/// as segment lists: `a::b` → `[[a, b]]`, `{a::x, b}` → `[[a, x], [b]]`, `*` → `[[]]`.
/// Returns them and the index after the expression.
fn parse_tail(tokens: &[Token], mut i: usize) -> (Vec<Vec<String>>, usize) {
    let mut prefix = Vec::new();
    loop {
        let Some(t) = tokens.get(i) else { return (vec![prefix], i) };
        if t.text == "{" {
            let mut all = Vec::new();
            i += 1;
            loop {
                match tokens.get(i).map(|t| t.text.as_str()) {
                    None => return (all, i),
                    Some("}") => return (all, i + 1),
                    Some(",") => i += 1,
                    Some(_) => {
                        let (items, next) = parse_tail(tokens, i);
                        all.extend(items.into_iter().map(|item| prefix.iter().cloned().chain(item).collect()));
                        // Skip `as name` and anything else up to the item's end.
                        i = next;
                        while let Some(t) = tokens.get(i) {
                            if t.text == "," || t.text == "}" {
                                break;
                            }
                            i += 1;
                        }
                    }
                }
            }
        }
        if t.text == "*" {
            return (vec![prefix], i + 1);
        }
        if !is_ident(&t.text) {
            return (vec![prefix], i);
        }
        prefix.push(t.text.clone());
        if tokens.get(i + 1).map(|t| t.text.as_str()) != Some("::") {
            return (vec![prefix], i + 1);
        }
        i += 2;
    }
}

fn is_ident(s: &str) -> bool {
    s.bytes().next().is_some_and(|c| c.is_ascii_alphabetic() || c == b'_' || c >= 0x80)
}

/// Every crate-internal path in `text` (a file whose module is `module`), resolved to an
/// absolute module path, with its line.
fn crate_paths(module: &[String], text: &str) -> Vec<(usize, Vec<String>)> {
    let tokens = tokenize(&blank_non_code(text));
    let mut out = Vec::new();
    // Inline modules: (name, brace depth inside it).
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut i = 0;
    while i < tokens.len() {
        let t = &tokens[i].text;
        match t.as_str() {
            "{" => depth += 1,
            "}" => {
                if inline.last().is_some_and(|(_, d)| *d == depth) {
                    inline.pop();
                }
                depth = depth.saturating_sub(1);
            }
            "mod" if tokens.get(i + 2).is_some_and(|t| t.text == "{") => {
                inline.push((tokens[i + 1].text.clone(), depth + 1));
            }
            "crate" | "super" | "self"
                if tokens.get(i + 1).is_some_and(|t| t.text == "::") && (i == 0 || tokens[i - 1].text != "::") =>
            {
                let here: Vec<String> = module.iter().cloned().chain(inline.iter().map(|(n, _)| n.clone())).collect();
                let line = tokens[i].line;
                // Resolve the leading crate / self / super… segments.
                let (mut base, mut j) = match t.as_str() {
                    "crate" => (Vec::new(), i + 2),
                    "self" => (here.clone(), i + 2),
                    _ => (here.clone(), i),
                };
                while tokens.get(j).is_some_and(|t| t.text == "super")
                    && tokens.get(j + 1).is_some_and(|t| t.text == "::")
                {
                    base.pop();
                    j += 2;
                }
                let (tails, next) = parse_tail(&tokens, j);
                for tail in tails {
                    out.push((line, base.iter().cloned().chain(tail).collect()));
                }
                i = next;
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    out
}

fn rank_of(top: Option<&str>) -> Option<u8> {
    match top {
        None => Some(ROOT_RANK),
        Some(m) => LAYERS.iter().find(|(name, _)| *name == m).map(|(_, r)| *r),
    }
}

/// The rule violations in one file.
fn check_file(relative: &str, text: &str, families: &BTreeSet<String>) -> Vec<Violation> {
    let module = module_of(relative);
    let from_top = module.first().map(String::as_str);
    let violation = |line, message| Violation { file: relative.to_owned(), line, message };
    let Some(from_rank) = rank_of(from_top) else {
        return vec![violation(1, format!("module `{}` is in no layer (add it to LAYERS)", module.join("::")))];
    };
    let from_family = (from_top == Some("builtin")).then(|| module.get(1)).flatten().filter(|f| families.contains(*f));
    let mut found = Vec::new();
    for (line, target) in crate_paths(&module, text) {
        let to_top = target.first().map(String::as_str);
        let Some(to_rank) = rank_of(to_top) else {
            found.push(violation(line, format!("imports `crate::{}`, which is in no layer", target.join("::"))));
            continue;
        };
        let shown = format!("crate::{}", target.join("::"));
        if to_rank > from_rank {
            found.push(violation(
                line,
                format!(
                    "`{}` (layer {from_rank}) imports `{shown}` (layer {to_rank}): a module may import only its own \
                     layer or lower ones",
                    from_top.unwrap_or("crate root")
                ),
            ));
            continue;
        }
        if let Some(family) = from_family
            && to_top == Some("builtin")
        {
            match target.get(1).filter(|f| families.contains(*f)) {
                Some(other) if other != family => found.push(violation(
                    line,
                    format!(
                        "node family `{family}` imports family `{other}` (`{shown}`): move what both need to \
                         `kernels` (or lower)"
                    ),
                )),
                Some(_) => {}
                None => found
                    .push(violation(line, format!("node family `{family}` imports the built-in registry (`{shown}`)"))),
            }
        }
    }
    found
}

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// Names of the node families: the modules directly under `builtin/`.
fn families(src: &Path) -> BTreeSet<String> {
    std::fs::read_dir(src.join("builtin"))
        .unwrap_or_else(|e| panic!("builtin/: {e}"))
        .flatten()
        .map(|e| e.path())
        .filter_map(|p| {
            let name = p.file_stem()?.to_string_lossy().into_owned();
            (p.is_dir() || (p.extension().is_some_and(|e| e == "rs") && name != "mod")).then_some(name)
        })
        .collect()
}

#[test]
fn no_module_imports_an_upper_layer_and_no_family_imports_another() {
    let src = src_dir();
    let families = families(&src);
    assert!(families.len() >= 10, "families found: {families:?}");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    assert!(files.len() > 50, "only {} files under {}", files.len(), src.display());
    let mut violations = Vec::new();
    let mut paths_seen = 0;
    for path in &files {
        let relative = path.strip_prefix(&src).unwrap_or(path).to_string_lossy().replace('\\', "/");
        let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        paths_seen += crate_paths(&module_of(&relative), &text).len();
        violations.extend(check_file(&relative, &text, &families));
    }
    // The scan must actually see the imports (a broken scanner would pass vacuously).
    assert!(paths_seen > 300, "only {paths_seen} crate paths found");
    let report: Vec<String> = violations.iter().map(ToString::to_string).collect();
    assert!(violations.is_empty(), "{} layer violation(s):\n{}", violations.len(), report.join("\n"));
}

#[test]
fn every_top_level_module_is_in_a_layer() {
    let lib = std::fs::read_to_string(src_dir().join("lib.rs")).unwrap_or_default();
    let code = blank_non_code(&lib);
    let tokens = tokenize(&code);
    let declared: Vec<&str> =
        tokens.windows(3).filter(|w| w[0].text == "mod" && w[2].text == ";").map(|w| w[1].text.as_str()).collect();
    assert!(declared.contains(&"kernels") && declared.contains(&"builtin"), "{declared:?}");
    for m in declared {
        assert!(rank_of(Some(m)).is_some(), "lib.rs declares `{m}`, which LAYERS does not place");
    }
}

/// The scanner on made-up files: each rule can fail, and comments, strings, same-family
/// and lower-layer imports do not trip it.
#[test]
fn the_check_catches_deliberately_bad_files() {
    let families: BTreeSet<String> =
        ["arm", "clip_edit", "ik", "momentum", "skin", "transitions"].into_iter().map(String::from).collect();
    let lines =
        |file: &str, text: &str| -> Vec<usize> { check_file(file, text, &families).iter().map(|v| v.line).collect() };

    // A kernel importing the contract; a model file importing a format through a group.
    assert_eq!(lines("kernels/foo.rs", "use crate::model::Clip;\nuse crate::node::Value;\n"), [2]);
    assert_eq!(lines("model/x.rs", "use crate::{math::slerp_short,\n    formats::FormatError};\n"), [1]);
    // The contract calling a built-in node inline, not in a `use`.
    assert_eq!(lines("node/mod.rs", "fn f(r: &mut Registry) {\n    crate::builtin::register(r);\n}\n"), [2]);
    // A family importing another, by `crate::` and by `super::` (resolved from the file).
    assert_eq!(lines("builtin/ik/roles.rs", "use crate::builtin::momentum::body::limb_tip;\n"), [1]);
    assert_eq!(lines("builtin/transitions/mod.rs", "use super::clip_edit::resample;\n"), [1]);
    assert_eq!(lines("builtin/ik/map.rs", "use super::super::momentum::into_report;\n"), [1]);
    // Same family through super::, and a lower layer: fine.
    assert!(
        lines("builtin/ik/map.rs", "use super::roles::roles_of;\nuse crate::kernels::body::limb_tip;\n").is_empty()
    );
    assert!(lines("builtin/transitions/graph.rs", "use super::cluster::Clusters;\n").is_empty());
    // A test module inside a family: `super::*` is the file itself, the other family is not.
    let test_module =
        "fn a() {}\n#[cfg(test)]\nmod tests {\n    use super::*;\n    use crate::builtin::skin::bind;\n}\n";
    assert_eq!(lines("builtin/arm.rs", test_module), [5]);
    // The same inside a kernel: `super::*` stays in the kernel, `crate::builtin` is flagged.
    assert_eq!(lines("kernels/arm.rs", test_module), [5]);
    // Comments, doc comments, strings and raw strings are not imports.
    let quiet = "// use crate::builtin::x;\n/// [`crate::node::Value`]\n/* crate::node */\nconst S: &str = \"crate::builtin::y\";\nconst R: &str = r#\"crate::node::\"#;\nconst C: char = '\"';\nfn f<'a>(x: &'a str) {}\n";
    assert!(lines("kernels/q.rs", quiet).is_empty(), "{:?}", check_file("kernels/q.rs", quiet, &families));
    // A module in no layer, and an import of one.
    assert_eq!(lines("scratch/x.rs", "fn f() {}\n"), [1]);
    assert_eq!(lines("kernels/y.rs", "use crate::scratch::Thing;\n"), [1]);
    // The message names the file, the line and both ends.
    let v = &check_file("kernels/foo.rs", "\n\nuse crate::builtin::skin::bind;\n", &families)[0];
    let shown = v.to_string();
    assert!(shown.starts_with("nodes/src/kernels/foo.rs:3:"), "{shown}");
    assert!(shown.contains("`kernels` (layer 3)") && shown.contains("crate::builtin::skin::bind"), "{shown}");
}

#[test]
fn module_paths_and_super_resolve_like_rustc() {
    assert_eq!(module_of("builtin/ik/map.rs"), ["builtin", "ik", "map"]);
    assert_eq!(module_of("kernels/mod.rs"), ["kernels"]);
    assert!(module_of("lib.rs").is_empty());
    let paths = crate_paths(
        &module_of("builtin/ik/map.rs"),
        "use super::{roles::X, rig::{IkRig, Dof}};\nuse self::inner::Y;\n",
    );
    let shown: Vec<String> = paths.iter().map(|(l, p)| format!("{l}:{}", p.join("::"))).collect();
    assert_eq!(
        shown,
        [
            "1:builtin::ik::roles::X",
            "1:builtin::ik::rig::IkRig",
            "1:builtin::ik::rig::Dof",
            "2:builtin::ik::map::inner::Y"
        ]
    );
}
