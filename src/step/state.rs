//! The checks every stepper makes of the state it is given before it touches anything: buffer
//! lengths, masses, finiteness, and the pinned flags read as one per vertex.

use super::super::element::Vector;
use super::super::math;
use super::super::types::Real;
use crate::error::{StepBuffer, StepError};

/// `Ok` if `actual == expected`, else [`StepError::LengthMismatch`].
#[inline]
pub(crate) fn check_length(
    buffer: StepBuffer,
    expected: usize,
    actual: usize,
) -> Result<(), StepError> {
    if actual == expected {
        Ok(())
    } else {
        Err(StepError::LengthMismatch {
            buffer,
            expected,
            actual,
        })
    }
}

/// Checks the buffers every stepper shares: masses (finite, positive), pinned flags (empty or
/// one per vertex), positions and optionally velocities (lengths, finite).
pub(crate) fn check_state<V: Vector>(
    vertex_count: usize,
    masses: &[Real],
    pinned: &[bool],
    positions: &[V],
    velocities: Option<&[V]>,
) -> Result<(), StepError> {
    check_state_lengths(vertex_count, masses, pinned, positions, velocities)?;
    if let Some(vertex) = first_bad_mass(masses) {
        return Err(StepError::Mass { vertex });
    }
    first_non_finite(positions, velocities.unwrap_or(&[]))
        .map_or(Ok(()), |vertex| Err(StepError::NonFiniteInput { vertex }))
}

/// The length checks of [`check_state`].
pub(crate) fn check_state_lengths<V>(
    vertex_count: usize,
    masses: &[Real],
    pinned: &[bool],
    positions: &[V],
    velocities: Option<&[V]>,
) -> Result<(), StepError> {
    check_length(StepBuffer::Positions, vertex_count, positions.len())?;
    if let Some(velocities) = velocities {
        check_length(StepBuffer::Velocities, vertex_count, velocities.len())?;
    }
    check_length(StepBuffer::Masses, vertex_count, masses.len())?;
    if !pinned.is_empty() {
        check_length(StepBuffer::Pinned, vertex_count, pinned.len())?;
    }
    Ok(())
}

/// The first of `masses` out of the steppers' range ([`mass_in_range`]).
pub(crate) fn first_bad_mass(masses: &[Real]) -> Option<usize> {
    masses.iter().position(|&m| !mass_in_range(m))
}

/// Whether `m` (kg) is a mass the steppers accept: a finite normal positive number, so that
/// `1 / m` is finite too (a subnormal mass such as `1e-39` in f32 has an infinite reciprocal).
#[inline]
pub(crate) fn mass_in_range(m: Real) -> bool {
    m >= Real::MIN_POSITIVE && m.is_finite()
}

/// The first vertex whose position or velocity (if given) is not finite.
pub(crate) fn first_non_finite<V: Vector>(positions: &[V], velocities: &[V]) -> Option<usize> {
    let velocity_ok = |i: usize| velocities.get(i).is_none_or(|v| v.is_finite());
    positions
        .iter()
        .enumerate()
        .position(|(i, x)| !(x.is_finite() && velocity_ok(i)))
}

/// The pinned flag of every vertex, `false` past the end of `pinned` (so an empty slice pins
/// nothing).
#[inline]
pub(crate) fn pinned_flags(pinned: &[bool]) -> impl Iterator<Item = bool> + '_ {
    pinned.iter().copied().chain(core::iter::repeat(false))
}

/// `|v|`.
#[inline(always)]
pub(crate) fn length<V: Vector>(v: V) -> Real {
    math::sqrt(v.dot(v))
}
