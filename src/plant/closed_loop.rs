//! The batch closed loop: a [`Controller`] driving the [`VirtualActuator`] sample by sample, as a user's loop
//! would (each sample the controller gets the reference, the angle and the torque measured at the sample before,
//! the actuator the command), with the angle's `sincos` computed once for both: the plant's seal friction and
//! the controller's friction feedforward read the same angle.
use super::virtual_actuator::{Sample, VirtualActuator};
use crate::compensator::Command;
use crate::controller::Controller;

/// Drive `plant` with `controller` along `reference_nmm` (N·mm, one value per plant sample) from their present
/// states; both advance. `theta_rad`: the angle (rad) the controller gets at each sample, default the plant's
/// own (the encoder angle of that sample); given, it is used as far as it reaches (the shorter input sets the
/// length). No measurement reaches the controller at the first sample (NaN). `each(i, command, sample,
/// controller)` sees every sample after both stepped. Outputs are those of `controller.step` and `plant.step`
/// called in turn, to the bit.
pub fn run_closed_loop<S: AsRef<[f64]>, const N: usize, const K: usize>(
    controller: &mut Controller<S, N, K>,
    plant: &mut VirtualActuator,
    reference_nmm: &[f64],
    theta_rad: Option<&[f64]>,
    mut each: impl FnMut(usize, &Command, &Sample, &Controller<S, N, K>),
) {
    let n = theta_rad.map_or(reference_nmm.len(), |t| t.len().min(reference_nmm.len()));
    let mut measured = f64::NAN;
    for (i, &r) in reference_nmm[..n].iter().enumerate() {
        let own = plant.theta_rad();
        let sincos = crate::trig::sincos(own);
        let th = theta_rad.map_or(own, |t| t[i]);
        // A given angle shares the plant's `sincos` only where it is the plant's angle to the bit.
        let c = if th.to_bits() == own.to_bits() {
            controller.step_with_sincos(r, th, measured, sincos)
        } else {
            controller.step(r, th, measured)
        };
        let s = plant.step_with_sincos(c.current_a, sincos);
        measured = s.torque_nmm;
        each(i, &c, &s, controller);
    }
}
