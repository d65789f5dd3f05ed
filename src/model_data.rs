//! A model's compensator as plain data: raw CBH tables, friction coefficients, converter gain, current limit and
//! the extension stages' parameters. `bmr export` writes it as `static` Rust items or C arrays; firmware (or the
//! C ABI in [`crate::ffi`]) turns it into a [`Compensator`] with [`ModelData::compensator`] — `no_std`, no
//! allocation, the tables borrowed for the compensator's lifetime. The same data gives the same commands, bit for
//! bit, as the Python `Compensator` it was exported from.
use crate::cbh::{Hysteresis, Initial};
use crate::compensator::{Compensator, CompensatorError, InverseKind};
use crate::error::{FamilyKind, TableError};
use crate::everett::Family;
use crate::friction::{Friction, FrictionError};
use crate::stages::StageError;
use crate::vocabulary::{EffectKind, MAX_PARAMS, ParamError, Params, SPECS};
use core::fmt;

/// Memory (reversal points) of the exported compensator: the Python operators' capacity, so that both remember
/// alike.
pub const MEMORY: usize = 64;

/// One extension stage: the effect's index in the vocabulary ([`EffectKind`] as `u32`) and its parameter values
/// in the vocabulary's order (unused ones 0).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffectValues {
    pub kind: u32,
    pub values: [f64; MAX_PARAMS],
}

/// Everything a compensator is built from (see the module doc). Tables are in [`Family`] layout: grid, reversal
/// inputs, then one row per curve.
#[derive(Clone, Copy, Debug)]
pub struct ModelData<'a> {
    pub ascending: &'a [f64],
    pub ascending_nodes: usize,
    pub ascending_curves: usize,
    pub descending: &'a [f64],
    pub descending_nodes: usize,
    pub descending_curves: usize,
    /// Output after negative and positive saturation (N·mm).
    pub y_lo: f64,
    pub y_hi: f64,
    /// Friction `c0` and sine/cosine coefficients of harmonics 1.. (N·mm), before the extensions.
    pub friction_c0: f64,
    pub friction_a: &'a [f64],
    pub friction_b: &'a [f64],
    pub converter_gain_a_per_v: f64,
    pub current_limit_a: f64,
    /// Full scale of the `non_congruent` output map when its `scale_nmm` is 0 (N·mm).
    pub full_torque_nmm: f64,
    pub effects: &'a [EffectValues],
}

/// Why a model could not be made into a compensator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BuildError {
    Table(TableError),
    Friction(FrictionError),
    Compensator(CompensatorError),
    /// Effect number `index` has a kind outside the vocabulary.
    UnknownEffect {
        index: usize,
        kind: u32,
    },
    /// Effect number `index` has a parameter outside its range.
    Param {
        index: usize,
        error: ParamError<'static>,
    },
}

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuildError::Table(e) => e.fmt(f),
            BuildError::Friction(e) => e.fmt(f),
            BuildError::Compensator(e) => e.fmt(f),
            BuildError::UnknownEffect { index, kind } => write!(
                f,
                "extension {index}: effect number {kind} is not in the vocabulary (0..{})",
                SPECS.len()
            ),
            BuildError::Param { index, error } => write!(f, "extension {index}: {error}"),
        }
    }
}

impl From<TableError> for BuildError {
    fn from(e: TableError) -> Self {
        BuildError::Table(e)
    }
}
impl From<FrictionError> for BuildError {
    fn from(e: FrictionError) -> Self {
        BuildError::Friction(e)
    }
}
impl From<CompensatorError> for BuildError {
    fn from(e: CompensatorError) -> Self {
        BuildError::Compensator(e)
    }
}

impl EffectValues {
    /// The values of validated parameters.
    pub fn of(p: &Params) -> Option<EffectValues> {
        let kind = EffectKind::from_name(p.spec.name)? as u32;
        let mut values = [0.0; MAX_PARAMS];
        values[..p.values().len()].copy_from_slice(p.values());
        Some(EffectValues { kind, values })
    }

    /// Validated parameters (the vocabulary's ranges); `index` names the entry in errors.
    pub fn params(&self, index: usize) -> Result<Params, BuildError> {
        let Some(spec) = SPECS.get(self.kind as usize) else {
            return Err(BuildError::UnknownEffect {
                index,
                kind: self.kind,
            });
        };
        let n = spec.params.len();
        let mut given: [(&'static str, f64); MAX_PARAMS] = [("", 0.0); MAX_PARAMS];
        for (g, (s, &v)) in given.iter_mut().zip(spec.params.iter().zip(&self.values)) {
            *g = (s.name, v);
        }
        Params::new(spec, &given[..n]).map_err(|error| BuildError::Param { index, error })
    }
}

impl<'a> ModelData<'a> {
    /// The forward operator (after negative saturation).
    pub fn hysteresis<const N: usize>(&self) -> Result<Hysteresis<&'a [f64], N>, BuildError> {
        let asc = Family::new(
            self.ascending,
            self.ascending_nodes,
            self.ascending_curves,
            FamilyKind::Ascending,
        )?;
        let desc = Family::new(
            self.descending,
            self.descending_nodes,
            self.descending_curves,
            FamilyKind::Descending,
        )?;
        Ok(Hysteresis::new(
            asc,
            desc,
            self.y_lo,
            self.y_hi,
            Initial::Negative,
        )?)
    }

    /// The compensator (exact inverse, after negative saturation) with its extension stages at control period
    /// `dt_s`.
    pub fn compensator<const N: usize, const K: usize>(
        &self,
        dt_s: f64,
    ) -> Result<Compensator<&'a [f64], N, K>, BuildError> {
        let friction =
            Friction::from_coefficients(self.friction_c0, self.friction_a, self.friction_b)?;
        let c = Compensator::new(
            self.hysteresis()?,
            InverseKind::Exact,
            friction,
            self.converter_gain_a_per_v,
            self.current_limit_a,
        )?;
        let mut params = [Params::defaults(&SPECS[0]); EffectKind::ALL.len()];
        if self.effects.len() > params.len() {
            // More entries than effects: one is given twice (or is not an effect).
            let index = params.len();
            let kind = self.effects[index].kind;
            return Err(match EffectKind::ALL.get(kind as usize) {
                Some(&k) => BuildError::Compensator(CompensatorError::Stage(StageError::Twice(k))),
                None => BuildError::UnknownEffect { index, kind },
            });
        }
        for (i, e) in self.effects.iter().enumerate() {
            params[i] = e.params(i)?;
        }
        Ok(c.with_extensions(&params[..self.effects.len()], dt_s, self.full_torque_nmm)?)
    }
}
