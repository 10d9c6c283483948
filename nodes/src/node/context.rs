//! What a node sees while it runs: its inputs, checked parameters, a warnings sink,
//! progress and cancellation, and the only sanctioned way to write files.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use super::param::{
    ChoiceParam, FloatParam, InputFolderParam, InputPathParam, IntParam, OutputPathParam, ParamValue, TextParam,
};
use super::port::{Input, Output};
use super::value::{PortValue, Value};
use super::{NodeError, NodeSchema};
use crate::cancel::Cancel;
use crate::formats::atomic::write_within_with;
use crate::model::choice::{Choice, not_one_of};
use crate::model::units::memory_size;

/// Per-run services shared by every node of one evaluation.
pub struct RunServices<'a> {
    /// Folder relative input paths resolve against (the graph file's folder).
    pub base_dir: &'a Path,
    /// Folder exports write into; `None` forbids writing (e.g. `kg check`).
    pub out_dir: Option<&'a Path>,
    /// Set to stop the run; nodes poll it through [`NodeContext::check_cancelled`].
    pub cancel: &'a AtomicBool,
    /// Bytes one node may plan to allocate; see [`NodeContext::reserve_memory`].
    pub memory_limit_bytes: u64,
}

/// One node's view of its evaluation.
pub struct NodeContext<'a> {
    schema: &'static NodeSchema,
    inputs: Vec<Option<Value>>,
    params: &'a BTreeMap<String, ParamValue>,
    services: &'a RunServices<'a>,
    progress: &'a (dyn Fn(f32) + Sync),
    outputs: Vec<Option<Value>>,
    warnings: Vec<String>,
    files_written: Vec<PathBuf>,
}

/// What a node produced.
#[derive(Debug, Default)]
pub struct NodeOutcome {
    /// Output values in schema order (`None` where the node set nothing).
    pub outputs: Vec<Option<Value>>,
    /// Warnings the node raised.
    pub warnings: Vec<String>,
    /// Files written, as absolute paths.
    pub files_written: Vec<PathBuf>,
}

impl<'a> NodeContext<'a> {
    /// Builds a context. `inputs` follow the schema's input order; `params` are already
    /// checked and hold every defaulted value.
    pub fn new(
        schema: &'static NodeSchema,
        inputs: Vec<Option<Value>>,
        params: &'a BTreeMap<String, ParamValue>,
        services: &'a RunServices<'a>,
        progress: &'a (dyn Fn(f32) + Sync),
    ) -> Self {
        NodeContext {
            schema,
            inputs,
            params,
            services,
            progress,
            outputs: vec![None; schema.outputs.len()],
            warnings: Vec::new(),
            files_written: Vec::new(),
        }
    }

    /// Ends the evaluation, handing back what the node produced.
    pub fn finish(self) -> NodeOutcome {
        NodeOutcome { outputs: self.outputs, warnings: self.warnings, files_written: self.files_written }
    }

    fn input_value(&self, name: &'static str) -> Option<&Value> {
        let index = self.schema.inputs.iter().position(|p| p.name == name)?;
        self.inputs.get(index)?.as_ref()
    }

    /// A required input's value.
    pub fn input<T: PortValue>(&self, port: &Input<T>) -> Result<T, NodeError> {
        self.optional_input(port)?.ok_or_else(|| NodeError::input(port.name(), "is not connected"))
    }

    /// An optional input's value, `None` when unconnected.
    pub fn optional_input<T: PortValue>(&self, port: &Input<T>) -> Result<Option<T>, NodeError> {
        match self.input_value(port.name()) {
            None => Ok(None),
            Some(v) => T::from_value(v).map(Some).ok_or_else(|| {
                NodeError::input(
                    port.name(),
                    format!("carries a {}, expected {}", v.port_type().name(), T::TYPE.name()),
                )
            }),
        }
    }

    /// Sets an output.
    pub fn set_output<T: PortValue>(&mut self, port: &Output<T>, value: T) {
        if let Some(index) = self.schema.outputs.iter().position(|p| p.name == port.name()) {
            self.outputs[index] = Some(value.into_value());
        }
    }

    fn param(&self, name: &'static str) -> Option<&ParamValue> {
        self.params.get(name)
    }

    /// A real parameter; fails only if the parameter is unset and has no default.
    pub fn float(&self, p: &FloatParam) -> Result<f64, NodeError> {
        self.optional_float(p)?.ok_or_else(|| NodeError::param(p.0.name, "is not set"))
    }

    /// A real parameter that may be unset.
    pub fn optional_float(&self, p: &FloatParam) -> Result<Option<f64>, NodeError> {
        Ok(self.param(p.0.name).and_then(ParamValue::as_f64))
    }

    /// A whole-number parameter that may be unset.
    pub fn optional_int(&self, p: &IntParam) -> Result<Option<i64>, NodeError> {
        match self.param(p.0.name) {
            None => Ok(None),
            Some(ParamValue::Int(i)) => Ok(Some(*i)),
            Some(other) => Err(NodeError::param(p.0.name, format!("expected a whole number, got {other}"))),
        }
    }

    /// A whole-number parameter.
    pub fn int(&self, p: &IntParam) -> Result<i64, NodeError> {
        self.optional_int(p)?.ok_or_else(|| NodeError::param(p.0.name, "is not set"))
    }

    fn text(&self, name: &'static str) -> Result<&str, NodeError> {
        match self.param(name) {
            Some(ParamValue::Text(s)) => Ok(s),
            Some(other) => Err(NodeError::param(name, format!("expected text, got {other}"))),
            None => Err(NodeError::param(name, "is not set")),
        }
    }

    /// A choice parameter, as its enum.
    pub fn choice<T: Choice>(&self, p: &ChoiceParam<T>) -> Result<T, NodeError> {
        let name = self.text(p.0.name)?;
        T::from_name(name).ok_or_else(|| NodeError::param(p.0.name, not_one_of(name, T::NAMES)))
    }

    /// A free-text parameter.
    pub fn text_param(&self, p: &TextParam) -> Result<&str, NodeError> {
        self.text(p.0.name)
    }

    /// An input file, resolved against the graph's folder.
    pub fn input_path(&self, p: &InputPathParam) -> Result<PathBuf, NodeError> {
        Ok(self.services.base_dir.join(self.text(p.0.name)?))
    }

    /// A folder named by a text parameter, resolved against the graph's folder.
    pub fn input_folder(&self, p: &InputFolderParam) -> Result<PathBuf, NodeError> {
        Ok(self.services.base_dir.join(self.text(p.0.name)?))
    }

    /// An optional input file, resolved against the graph's folder; `None` when unset.
    pub fn optional_input_path(&self, p: &InputPathParam) -> Result<Option<PathBuf>, NodeError> {
        if self.param(p.0.name).is_none() { Ok(None) } else { self.input_path(p).map(Some) }
    }

    /// Writes `bytes` atomically to the output file named by `p`, inside the run's output
    /// folder, and returns the path relative to that folder.
    pub fn write_output(&mut self, p: &OutputPathParam, bytes: &[u8]) -> Result<PathBuf, NodeError> {
        self.write_output_with(p, |out| out.write_all(bytes))
    }

    /// [`NodeContext::write_output`] for a writer that streams its bytes (a large export
    /// then never holds its whole file in memory).
    pub fn write_output_with(
        &mut self,
        p: &OutputPathParam,
        write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
    ) -> Result<PathBuf, NodeError> {
        let relative = PathBuf::from(self.text(p.0.name)?);
        self.write_relative(relative, write)
    }

    fn write_relative(
        &mut self,
        relative: PathBuf,
        write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
    ) -> Result<PathBuf, NodeError> {
        let out_dir = self
            .services
            .out_dir
            .ok_or_else(|| NodeError::Failed("this run has no output folder, so nothing may be written".into()))?;
        self.check_cancelled()?;
        let path = write_within_with(out_dir, &relative, write)?;
        self.files_written.push(path);
        Ok(relative)
    }

    /// Writes frame `frame` of a sequence atomically beside the output file named by `p`:
    /// `dir/name.ext` becomes `dir/name_0007.ext` (four digits, more when needed), and
    /// returns that path relative to the output folder.
    pub fn write_output_frame(
        &mut self,
        p: &OutputPathParam,
        frame: usize,
        bytes: &[u8],
    ) -> Result<PathBuf, NodeError> {
        let named = PathBuf::from(self.text(p.0.name)?);
        let stem = named.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let extension = named.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
        self.write_relative(named.with_file_name(format!("{stem}_{frame:04}.{extension}")), |out| out.write_all(bytes))
    }

    /// Records a warning: something odd that does not stop the run.
    pub fn warn(&mut self, message: impl Into<String>) {
        self.warnings.push(message.into());
    }

    /// Records several warnings.
    pub fn warn_all(&mut self, messages: impl IntoIterator<Item = String>) {
        self.warnings.extend(messages);
    }

    /// Reports progress of this node, from 0 to 1.
    pub fn progress(&self, fraction: f32) {
        (self.progress)(fraction.clamp(0.0, 1.0));
    }

    /// Fails with [`NodeError::Cancelled`] once the run has been cancelled.
    pub fn check_cancelled(&self) -> Result<(), NodeError> {
        Ok(self.cancel().check()?)
    }

    /// The run's memory limit in bytes, for kernels that learn a size only while reading
    /// data (file readers) and refuse past it themselves.
    pub fn memory_limit_bytes(&self) -> u64 {
        self.services.memory_limit_bytes
    }

    /// Refuses when the node is about to allocate about `bytes` (an estimate from its
    /// params and inputs) and that exceeds the run's memory limit, so a huge request fails
    /// with a located message instead of an out-of-memory abort. `culprit` is the param
    /// (or, when the size comes from data, the input port) the message tells to change.
    pub fn reserve_memory(&self, bytes: u64, culprit: &'static str) -> Result<(), NodeError> {
        let limit = self.services.memory_limit_bytes;
        if bytes <= limit {
            return Ok(());
        }
        let is_input = self.schema.input(culprit).is_some();
        let message = format!(
            "needs about {} of memory, more than the limit of {} (80 % of the machine's memory, or kg --max-memory); {}",
            memory_size(bytes as f64),
            memory_size(limit as f64),
            if is_input { "give a smaller one" } else { "lower it" }
        );
        Err(if is_input { NodeError::input(culprit, message) } else { NodeError::param(culprit, message) })
    }

    /// The run's stop request, for kernels that work long enough to poll it themselves.
    pub fn cancel(&self) -> Cancel<'a> {
        Cancel::on(self.services.cancel)
    }
}
