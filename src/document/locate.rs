//! Finds where a node, parameter or edge is written in a graph file, so validation
//! messages can give `file:line:column`. RON deserialisation keeps no spans, so this
//! searches the text for the quoted keys the (sorted, pretty) files contain.

/// Line lookups into a graph file's text.
#[derive(Clone, Debug, Default)]
pub struct SourceMap {
    text: String,
}

impl SourceMap {
    /// Indexes `text`.
    pub fn new(text: &str) -> Self {
        SourceMap { text: text.to_string() }
    }

    fn line_col(&self, offset: usize) -> (usize, usize) {
        let before = &self.text[..offset];
        let line = before.matches('\n').count() + 1;
        let column = before.rfind('\n').map_or(offset, |nl| offset - nl - 1) + 1;
        (line, column)
    }

    /// Offset of the first `"key"` followed by `:` at or after `from`.
    fn find_key(&self, key: &str, from: usize) -> Option<usize> {
        let quoted = format!("\"{key}\"");
        let mut start = from;
        while let Some(found) = self.text.get(start..)?.find(&quoted) {
            let at = start + found;
            let rest = self.text[at + quoted.len()..].trim_start();
            if rest.starts_with(':') {
                return Some(at);
            }
            start = at + quoted.len();
        }
        None
    }

    fn nodes_section(&self) -> usize {
        self.text.find("nodes").unwrap_or(0)
    }

    /// Where node `id` is declared.
    pub fn node(&self, id: &str) -> Option<(usize, usize)> {
        self.find_key(id, self.nodes_section()).map(|o| self.line_col(o))
    }

    /// Where parameter `param` of node `id` is set (or the node, when it is not set).
    pub fn param(&self, id: &str, param: &str) -> Option<(usize, usize)> {
        let node = self.find_key(id, self.nodes_section())?;
        let end = self.text[node..].find("),").map_or(self.text.len(), |e| node + e);
        match self.find_key(param, node) {
            Some(o) if o < end => Some(self.line_col(o)),
            _ => Some(self.line_col(node)),
        }
    }

    /// Where an edge mentioning `endpoint` (e.g. `"load.clip"`) is written.
    pub fn edge(&self, endpoint: &str) -> Option<(usize, usize)> {
        let edges = self.text.find("edges")?;
        let quoted = format!("\"{endpoint}\"");
        self.text[edges..].find(&quoted).map(|o| self.line_col(edges + o))
    }

    /// Where graph input `name` is declared.
    pub fn input(&self, name: &str) -> Option<(usize, usize)> {
        self.find_key(name, 0).map(|o| self.line_col(o))
    }
}
