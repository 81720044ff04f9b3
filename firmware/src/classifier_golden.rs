//! Golden vectors of the int8 classifier: features in, int8 inputs, int8 logits, class and
//! confidence out, computed on the host by the exported model's own arithmetic and checked
//! against the model compiled into the core ([`pbm::classifier::model_weights::MODEL`]).
//!
//! File `tests/golden/classifier_golden.txt` (written by `host-sim train --golden`): `#` comment
//! lines, then one vector per line, fields separated by `|`:
//!
//! - `x H H …`: the features, each the 16 hex digits of `f64::to_bits`;
//! - then either `implausible` (the input map must reject the features:
//!   [`ModelError::Implausible`]), or `q I I …` (the int8 inputs), `logits I I …` (the int8
//!   logits), `class LABEL` ([`pbm::FaultClass::label`]) and `conf N` (confidence, per cent).
//!
//! The check of a vector is [`QuantModel::quantize_input`] on the features, then
//! [`QuantModel::infer`] on the int8 inputs (the network alone, without the class-region guard).
//!
//! This module uses `core` only: the host test `tests/classifier_golden.rs` includes the same
//! source file, so the host and the firmware (`classifier-check` in QEMU) read the file and
//! check the model with one implementation.

use core::fmt;

use pbm::classifier::{ModelError, QuantModel, MAX_CLASSES, MAX_WIDTH};

/// What the file says the model must do with one vector's features.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expected<'a> {
    /// The input map rejects the features as implausible.
    Implausible,
    /// The network's output.
    Output {
        /// int8 inputs.
        q: Ints<i8, MAX_WIDTH>,
        /// int8 logits, one per class.
        logits: Ints<i8, MAX_CLASSES>,
        /// Label of the winning class.
        class: &'a str,
        /// Confidence of the winner, per cent.
        confidence_pct: u8,
    },
}

/// One golden vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vector<'a> {
    /// 1-based line number in the file.
    pub line: usize,
    /// The features.
    pub x: Floats,
    /// What the model must produce.
    pub expected: Expected<'a>,
}

/// Up to `N` integers, in file order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ints<T, const N: usize> {
    items: [T; N],
    len: usize,
}

impl<T: Copy + Default + core::str::FromStr, const N: usize> Ints<T, N> {
    fn parse(field: &str, key: &str) -> Option<Self> {
        let rest = field.trim().strip_prefix(key)?.strip_prefix(' ')?;
        let mut out = Self { items: [T::default(); N], len: 0 };
        for token in rest.split_whitespace() {
            let slot = out.items.get_mut(out.len)?;
            *slot = token.parse().ok()?;
            out.len += 1;
        }
        Some(out)
    }
}

impl<T, const N: usize> Ints<T, N> {
    /// The integers.
    pub fn as_slice(&self) -> &[T] {
        self.items.get(..self.len).unwrap_or(&[])
    }

    /// Mutable access (the firmware's self-test perturbs one expected value).
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        self.items.get_mut(..self.len).unwrap_or(&mut [])
    }
}

/// The features of a vector, at most [`MAX_WIDTH`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Floats {
    items: [f64; MAX_WIDTH],
    len: usize,
}

impl Floats {
    fn parse(field: &str) -> Option<Self> {
        let rest = field.trim().strip_prefix("x ")?;
        let mut out = Self { items: [0.0; MAX_WIDTH], len: 0 };
        for token in rest.split_whitespace() {
            let slot = out.items.get_mut(out.len)?;
            if token.len() != 16 {
                return None;
            }
            *slot = f64::from_bits(u64::from_str_radix(token, 16).ok()?);
            out.len += 1;
        }
        (out.len > 0).then_some(out)
    }

    /// The features.
    pub fn as_slice(&self) -> &[f64] {
        self.items.get(..self.len).unwrap_or(&[])
    }
}

/// A line that is not a golden vector (1-based line number).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadLine {
    /// Line number.
    pub line: usize,
}

impl fmt::Display for BadLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: not `x … | implausible` or `x … | q … | logits … | class … | conf …`", self.line)
    }
}

/// The vectors of a golden file, in file order (comment and blank lines skipped); never panics,
/// whatever the text.
pub fn vectors(text: &str) -> impl Iterator<Item = Result<Vector<'_>, BadLine>> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim_start().starts_with('#') && !l.trim().is_empty())
        .map(|(i, l)| parse_line(i + 1, l).ok_or(BadLine { line: i + 1 }))
}

fn parse_line(line: usize, text: &str) -> Option<Vector<'_>> {
    let mut fields = text.split('|');
    let x = Floats::parse(fields.next()?)?;
    let second = fields.next()?;
    let expected = if second.trim() == "implausible" {
        Expected::Implausible
    } else {
        let q = Ints::parse(second, "q")?;
        let logits = Ints::parse(fields.next()?, "logits")?;
        let class = fields.next()?.trim().strip_prefix("class ")?.trim();
        let conf = Ints::<u8, 1>::parse(fields.next()?, "conf")?;
        let &[confidence_pct] = conf.as_slice() else { return None };
        Expected::Output { q, logits, class, confidence_pct }
    };
    if fields.next().is_some() {
        return None;
    }
    Some(Vector { line, x, expected })
}

/// How the model disagrees with a vector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mismatch {
    /// The vector is implausible but the input map accepted it (or failed otherwise).
    NotImplausible(Option<ModelError>),
    /// The input map rejected features the file maps.
    Quantize(ModelError),
    /// Different int8 inputs.
    Inputs,
    /// The inference failed.
    Infer(ModelError),
    /// Different logits.
    Logits,
    /// A different winning class.
    Class,
    /// A different confidence.
    Confidence,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotImplausible(e) => write!(f, "expected implausible, input map said {e:?}"),
            Self::Quantize(e) => write!(f, "input map rejected the features: {e:?}"),
            Self::Inputs => write!(f, "int8 inputs differ"),
            Self::Infer(e) => write!(f, "inference failed: {e:?}"),
            Self::Logits => write!(f, "logits differ"),
            Self::Class => write!(f, "class differs"),
            Self::Confidence => write!(f, "confidence differs"),
        }
    }
}

/// Checks one vector against `model`: [`QuantModel::quantize_input`], then [`QuantModel::infer`].
pub fn check(model: &QuantModel<'_>, v: &Vector<'_>) -> Result<(), Mismatch> {
    let x = v.x.as_slice();
    let mut q = [0i8; MAX_WIDTH];
    let q = q.get_mut(..x.len()).ok_or(Mismatch::Quantize(ModelError::Shape))?;
    let quantized = model.quantize_input(x, q);
    let Expected::Output { q: want_q, logits, class, confidence_pct } = v.expected else {
        return match quantized {
            Err(ModelError::Implausible { .. }) => Ok(()),
            Err(e) => Err(Mismatch::NotImplausible(Some(e))),
            Ok(()) => Err(Mismatch::NotImplausible(None)),
        };
    };
    quantized.map_err(Mismatch::Quantize)?;
    if *q != *want_q.as_slice() {
        return Err(Mismatch::Inputs);
    }
    let inf = model.infer(q).map_err(Mismatch::Infer)?;
    if inf.logits.get(..inf.n_classes) != Some(logits.as_slice()) {
        return Err(Mismatch::Logits);
    }
    if inf.class.label() != class {
        return Err(Mismatch::Class);
    }
    if inf.confidence_pct != confidence_pct {
        return Err(Mismatch::Confidence);
    }
    Ok(())
}

/// What checking a whole file found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Summary {
    /// Vectors whose network output matched.
    pub matched: usize,
    /// Implausible vectors rejected as they must be.
    pub implausible: usize,
    /// Vectors that did not match, and lines that are not vectors.
    pub failures: usize,
    /// The first failure: line number and what differed (`None`: the line is not a vector).
    pub first_failure: Option<(usize, Option<Mismatch>)>,
}

impl Summary {
    /// Every line checked out, with at least `min_matched` network outputs and one implausible
    /// vector (the file must exercise both paths).
    pub fn passed(&self, min_matched: usize) -> bool {
        self.failures == 0 && self.matched >= min_matched && self.implausible >= 1
    }

    /// Counts the result of one vector.
    pub fn add(&mut self, v: &Vector<'_>, result: Result<(), Mismatch>) {
        match (result, v.expected) {
            (Ok(()), Expected::Implausible) => self.implausible += 1,
            (Ok(()), Expected::Output { .. }) => self.matched += 1,
            (Err(m), _) => self.fail(v.line, Some(m)),
        }
    }

    fn fail(&mut self, line: usize, why: Option<Mismatch>) {
        self.failures += 1;
        if self.first_failure.is_none() {
            self.first_failure = Some((line, why));
        }
    }
}

/// Checks every vector of `text` against `model`; `adjust` may change each vector before its
/// check (the firmware's self-test perturbs one).
pub fn check_all(model: &QuantModel<'_>, text: &str, mut adjust: impl FnMut(&mut Vector<'_>)) -> Summary {
    let mut s = Summary::default();
    for v in vectors(text) {
        match v {
            Ok(mut v) => {
                adjust(&mut v);
                s.add(&v, check(model, &v));
            }
            Err(BadLine { line }) => s.fail(line, None),
        }
    }
    s
}
