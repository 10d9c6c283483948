//! Where a node, parameter, edge or graph input is written in a graph file, so messages can
//! give `file:line:column`.
//!
//! The `ron` crate reports spans for syntax errors only, so this reads the file's token
//! structure itself: strings (with escapes), raw strings, comments and brackets are lexed,
//! and every map key and struct field is recorded under its path from the top
//! (`nodes/"trim"/params/"fps"`). A word inside a description or a comment is never taken
//! for a key, and keys are found at their own nesting level only.

use std::collections::BTreeMap;

/// Positions of the keys and edge endpoints of a graph file.
#[derive(Clone, Debug, Default)]
pub struct SourceMap {
    /// Byte offset of every key, by its path (`["nodes", "trim", "params", "fps"]`).
    keys: BTreeMap<Vec<String>, usize>,
    /// Edge endpoint strings with their offsets, in file order.
    endpoints: Vec<(String, usize)>,
    /// Start offset of each line.
    line_starts: Vec<usize>,
    text: String,
    /// Whether the file has `//` or `/* */` comments (the canonical form has none).
    has_comments: bool,
}

impl SourceMap {
    /// Indexes `text` (a graph file). Text that does not lex stays partly indexed: the
    /// loader reports the syntax error itself.
    pub fn new(text: &str) -> Self {
        let (tokens, has_comments) = lex(text);
        let mut walker = Walker { tokens: &tokens, at: 0, keys: BTreeMap::new(), endpoints: Vec::new() };
        walker.value(&mut Vec::new());
        let mut line_starts = vec![0];
        line_starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        SourceMap { keys: walker.keys, endpoints: walker.endpoints, line_starts, text: text.to_string(), has_comments }
    }

    fn line_col(&self, offset: usize) -> (usize, usize) {
        let line = self.line_starts.partition_point(|&s| s <= offset);
        let start = self.line_starts[line - 1];
        let column = self.text.get(start..offset).map_or(offset - start, |s| s.chars().count()) + 1;
        (line, column)
    }

    fn key(&self, path: &[&str]) -> Option<(usize, usize)> {
        let path: Vec<String> = path.iter().map(|s| s.to_string()).collect();
        self.keys.get(&path).map(|&o| self.line_col(o))
    }

    /// Where node `id` is declared.
    pub fn node(&self, id: &str) -> Option<(usize, usize)> {
        self.key(&["nodes", id])
    }

    /// Where parameter `param` of node `id` is set (or the node, when it is not set).
    pub fn param(&self, id: &str, param: &str) -> Option<(usize, usize)> {
        self.key(&["nodes", id, "params", param]).or_else(|| self.node(id))
    }

    /// Where an edge names `endpoint` (e.g. `"load.clip"`), first in file order.
    pub fn edge(&self, endpoint: &str) -> Option<(usize, usize)> {
        self.endpoints.iter().find(|(e, _)| e == endpoint).map(|&(_, o)| self.line_col(o))
    }

    /// Where graph input `name` is declared.
    pub fn input(&self, name: &str) -> Option<(usize, usize)> {
        self.key(&["inputs", name])
    }

    /// Whether the file holds comments, which rewriting it in canonical form would drop.
    pub fn has_comments(&self) -> bool {
        self.has_comments
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Open(char),
    Close,
    Colon,
    Comma,
    Str(String),
    Word(String),
}

/// Tokens with their byte offsets (comments and whitespace dropped), and whether there
/// were comments.
fn lex(text: &str) -> (Vec<(Tok, usize)>, bool) {
    let mut out = Vec::new();
    let mut comments = false;
    let mut chars = text.char_indices().peekable();
    while let Some((at, c)) = chars.next() {
        match c {
            '(' | '[' | '{' => out.push((Tok::Open(c), at)),
            ')' | ']' | '}' => out.push((Tok::Close, at)),
            ':' => out.push((Tok::Colon, at)),
            ',' => out.push((Tok::Comma, at)),
            '"' => out.push((Tok::Str(quoted(&mut chars)), at)),
            '/' if chars.peek().is_some_and(|&(_, n)| n == '/') => {
                comments = true;
                for (_, n) in chars.by_ref() {
                    if n == '\n' {
                        break;
                    }
                }
            }
            '/' if chars.peek().is_some_and(|&(_, n)| n == '*') => {
                comments = true;
                chars.next();
                let mut depth = 1;
                let mut prev = ' ';
                for (_, n) in chars.by_ref() {
                    match (prev, n) {
                        ('*', '/') => depth -= 1,
                        ('/', '*') => depth += 1,
                        _ => {}
                    }
                    if depth == 0 {
                        break;
                    }
                    prev = if (prev == '*' && n == '/') || (prev == '/' && n == '*') { ' ' } else { n };
                }
            }
            'r' if matches!(chars.peek(), Some((_, '#' | '"'))) => {
                let mut hashes = 0;
                while chars.next_if(|&(_, n)| n == '#').is_some() {
                    hashes += 1;
                }
                if chars.next_if(|&(_, n)| n == '"').is_none() {
                    out.push((Tok::Word("r".into()), at));
                    continue;
                }
                out.push((Tok::Str(raw(&mut chars, hashes)), at));
            }
            c if c.is_whitespace() => {}
            _ => {
                let mut word = c.to_string();
                while let Some((_, n)) = chars.next_if(|&(_, n)| !n.is_whitespace() && !"()[]{}:,\"/".contains(n)) {
                    word.push(n);
                }
                out.push((Tok::Word(word), at));
            }
        }
    }
    (out, comments)
}

/// The rest of a `"…"` string, unescaped (RON's escapes are Rust's).
fn quoted(chars: &mut std::iter::Peekable<std::str::CharIndices<'_>>) -> String {
    let mut s = String::new();
    while let Some((_, c)) = chars.next() {
        match c {
            '"' => break,
            '\\' => match chars.next().map(|(_, e)| e) {
                Some('n') => s.push('\n'),
                Some('t') => s.push('\t'),
                Some('r') => s.push('\r'),
                Some('0') => s.push('\0'),
                Some('u') => {
                    let mut hex = String::new();
                    for (_, h) in chars.by_ref() {
                        match h {
                            '{' => {}
                            '}' => break,
                            h => hex.push(h),
                        }
                    }
                    s.extend(u32::from_str_radix(&hex, 16).ok().and_then(char::from_u32));
                }
                Some('x') => {
                    let hex: String = chars.by_ref().take(2).map(|(_, h)| h).collect();
                    s.extend(u32::from_str_radix(&hex, 16).ok().and_then(char::from_u32));
                }
                Some(other) => s.push(other),
                None => break,
            },
            c => s.push(c),
        }
    }
    s
}

/// The rest of a raw string `r#"…"#` with `hashes` hashes.
fn raw(chars: &mut std::iter::Peekable<std::str::CharIndices<'_>>, hashes: usize) -> String {
    let mut s = String::new();
    while let Some((_, c)) = chars.next() {
        if c == '"' {
            let mut seen = 0;
            while seen < hashes && chars.next_if(|&(_, n)| n == '#').is_some() {
                seen += 1;
            }
            if seen == hashes {
                break;
            }
            s.push('"');
            s.extend(std::iter::repeat_n('#', seen));
        } else {
            s.push(c);
        }
    }
    s
}

/// Walks the tokens as RON values, recording keys by path and the strings under `edges`.
struct Walker<'t> {
    tokens: &'t [(Tok, usize)],
    at: usize,
    keys: BTreeMap<Vec<String>, usize>,
    endpoints: Vec<(String, usize)>,
}

impl Walker<'_> {
    fn peek(&self, ahead: usize) -> Option<&Tok> {
        self.tokens.get(self.at + ahead).map(|(t, _)| t)
    }

    fn bump(&mut self) -> Option<(Tok, usize)> {
        let t = self.tokens.get(self.at).cloned();
        self.at += 1;
        t
    }

    /// One value at `path`.
    fn value(&mut self, path: &mut Vec<String>) {
        // A named struct or variant (`Some(…)`, `GraphDoc(…)`) is its group.
        if matches!(self.peek(0), Some(Tok::Word(_))) && matches!(self.peek(1), Some(Tok::Open('('))) {
            self.at += 1;
        }
        match self.bump() {
            Some((Tok::Open('{'), _)) => self.entries(path, true),
            Some((Tok::Open(_), _)) => {
                let is_struct = matches!(self.peek(0), Some(Tok::Word(_))) && matches!(self.peek(1), Some(Tok::Colon));
                if is_struct { self.entries(path, false) } else { self.elements(path) }
            }
            Some((Tok::Str(s), at)) if path.first().is_some_and(|p| p == "edges") && path.len() == 3 => {
                self.endpoints.push((s, at));
            }
            _ => {}
        }
    }

    /// `key: value` pairs up to the closing bracket; map keys are values, struct keys words.
    fn entries(&mut self, path: &mut Vec<String>, map: bool) {
        loop {
            let key = match self.bump() {
                None | Some((Tok::Close, _)) => return,
                Some((Tok::Comma, _)) => continue,
                Some((Tok::Str(k), at)) if map => Some((k, at)),
                Some((Tok::Word(k), at)) => Some((k, at)),
                Some((Tok::Open(_), _)) => {
                    // A bracketed map key: skip it whole.
                    self.skip_group();
                    None
                }
                Some(_) => None,
            };
            if !matches!(self.bump(), Some((Tok::Colon, _))) {
                return;
            }
            match key {
                Some((k, at)) => {
                    path.push(k);
                    self.keys.entry(path.clone()).or_insert(at);
                    self.value(path);
                    path.pop();
                }
                None => self.value(path),
            }
        }
    }

    /// List or tuple elements up to the closing bracket, indexed.
    fn elements(&mut self, path: &mut Vec<String>) {
        let mut index = 0;
        loop {
            match self.peek(0) {
                None => return,
                Some(Tok::Close) => {
                    self.at += 1;
                    return;
                }
                Some(Tok::Comma) => {
                    self.at += 1;
                    continue;
                }
                Some(_) => {}
            }
            path.push(index.to_string());
            let before = self.at;
            self.value(path);
            path.pop();
            if self.at == before {
                self.at += 1;
            }
            index += 1;
        }
    }

    fn skip_group(&mut self) {
        let mut depth = 1;
        while depth > 0 {
            match self.bump() {
                None => return,
                Some((Tok::Open(_), _)) => depth += 1,
                Some((Tok::Close, _)) => depth -= 1,
                _ => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = r##"(
    format: "kinegraph.graph", version: 2,
    description: "nodes: { \"trim\": here } // not a key",
    /* "inputs": { "x": "y" } */
    inputs: { "rate": "re.sample.fps" },
    nodes: {
        // "trim": commented out
        "re.sample": (kind: "clip.resample", params: { "fps": 24.0 }),
        "trim": (kind: "clip.trim", params: { "start_secs": 0.0, "end_secs": r#"x"# }),
    },
    edges: [ (from: "trim.clip", to: "re.sample.clip") ],
)"##;

    #[test]
    fn keys_are_found_at_their_own_level_only() {
        let map = SourceMap::new(TEXT);
        assert_eq!(map.input("rate"), Some((5, 15)));
        assert_eq!(map.node("re.sample"), Some((8, 9)));
        assert_eq!(map.param("re.sample", "fps"), Some((8, 56)));
        assert_eq!(map.node("trim"), Some((9, 9)));
        assert_eq!(map.param("trim", "end_secs"), Some((9, 66)));
        assert_eq!(map.param("trim", "nothing"), map.node("trim"), "an unset param points at its node");
        assert_eq!(map.edge("re.sample.clip"), Some((11, 38)));
        assert_eq!(map.input("x"), None, "keys inside comments are not keys");
        assert_eq!(map.node("nothing"), None);
        assert!(map.has_comments());
        assert!(!SourceMap::new("(nodes: { \"a//b\": (kind: \"x/*y*/\") })").has_comments());
    }

    #[test]
    fn a_description_that_mentions_nodes_shifts_nothing() {
        let plain = SourceMap::new(&TEXT.replace(r#"nodes: { \"trim\": here } // not a key"#, "plain"));
        let tricky = SourceMap::new(TEXT);
        assert_eq!(plain.node("trim"), tricky.node("trim"));
        assert_eq!(plain.param("trim", "end_secs"), tricky.param("trim", "end_secs"));
    }
}
