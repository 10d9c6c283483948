//! Plain numbers: constants and sums, for wiring parameters and for engine tests.

use crate::node::{FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, Registry};

/// Registers the scalar nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(Constant));
    registry.add(Box::new(Add));
}

const VALUE: FloatParam = FloatParam::new("value", "The number to output.", 0.0, -1e12, 1e12, "");
const OUT: Output<f64> = Output::new("value", "The number.");

/// `scalar.constant`: outputs its parameter.
pub struct Constant;

static CONSTANT: NodeSchema = NodeSchema {
    kind: "scalar.constant",
    category: "scalar",
    doc: "Outputs a fixed number.",
    inputs: &[],
    outputs: &[OUT.spec()],
    params: &[VALUE.0],
    writes_files: false,
    version: 1,
};

impl Node for Constant {
    fn schema(&self) -> &'static NodeSchema {
        &CONSTANT
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let v = ctx.float(&VALUE)?;
        ctx.set_output(&OUT, v);
        Ok(())
    }
}

const A: Input<f64> = Input::required("a", "First number.");
const B: Input<f64> = Input::optional("b", "Second number (0 when unconnected).");
const OFFSET: FloatParam = FloatParam::new("offset", "Added to the sum.", 0.0, -1e12, 1e12, "");
const SUM: Output<f64> = Output::new("sum", "a + b + offset.");

/// `scalar.add`: adds its inputs and an offset.
pub struct Add;

static ADD: NodeSchema = NodeSchema {
    kind: "scalar.add",
    category: "scalar",
    doc: "Adds two numbers and a constant offset.",
    inputs: &[A.spec(), B.spec()],
    outputs: &[SUM.spec()],
    params: &[OFFSET.0],
    writes_files: false,
    version: 1,
};

impl Node for Add {
    fn schema(&self) -> &'static NodeSchema {
        &ADD
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let sum = ctx.input(&A)? + ctx.optional_input(&B)?.unwrap_or(0.0) + ctx.float(&OFFSET)?;
        ctx.set_output(&SUM, sum);
        Ok(())
    }
}
