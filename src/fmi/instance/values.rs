//! Variable access: fmi2Get/fmi2Set of Real, Integer, Boolean and String values through the
//! variable table, and the input derivatives of fmi2SetRealInputDerivatives.
use super::inputs::{BoundaryTiming, GravitySource};
use super::lifecycle::{Instance, Mode};
use super::status::{FmiError, FmiResult};
use crate::fmi::variables::{Causality, Quantity, VarType, Variable, VariableTable};
use crate::scene::limits::num;

impl Instance {
    fn var(&self, vr: u32, ty: VarType) -> FmiResult<&Variable> {
        let v = self.table.get(vr).ok_or_else(|| {
            FmiError::Invalid(format!(
                "unknown value reference {vr} (this FMU has {} variables, 0..{})",
                self.table.vars.len(),
                self.table.vars.len().saturating_sub(1)
            ))
        })?;
        if v.ty != ty {
            return Err(FmiError::Invalid(format!(
                "value reference {vr} ('{}') is a {} variable, not {}",
                v.name,
                v.ty.name(),
                ty.name()
            )));
        }
        Ok(v)
    }

    const GET_MODES: [Mode; 4] = [
        Mode::InitializationMode,
        Mode::StepComplete,
        Mode::Error,
        Mode::Terminated,
    ];

    fn value(&self, vr: u32, ty: VarType) -> FmiResult<f64> {
        let v = self.var(vr, ty)?;
        Ok(match v.quantity {
            q @ (Quantity::Density(_)
            | Quantity::Young(_)
            | Quantity::Poisson(_)
            | Quantity::SolverDt
            | Quantity::Damping
            | Quantity::FractureStrain) => {
                VariableTable::parameter_value(&self.params, q).unwrap_or(0.0)
            }
            Quantity::Gravity(k) => self.inputs.gravity[k],
            Quantity::GroupDisplacement(g, k) => self.inputs.displacement[g][k],
            Quantity::Load(r, k) => self.inputs.load[r][k],
            Quantity::GravitySource => self.inputs.gravity_source as i32 as f64,
            Quantity::BoundaryTiming => self.inputs.boundary_timing as i32 as f64,
            _ => self.outputs[vr as usize],
        })
    }

    fn prepare_get(&mut self, function: &str) -> FmiResult<()> {
        self.require(function, &Self::GET_MODES)?;
        if self.mode == Mode::InitializationMode && self.stale {
            self.build()?;
        }
        Ok(())
    }

    /// fmi2GetReal.
    pub fn get_real(&mut self, vr: &[u32], out: &mut [f64]) -> FmiResult<()> {
        self.prepare_get("fmi2GetReal")?;
        if vr.iter().any(|&r| {
            self.table.get(r).is_some_and(|v| {
                matches!(v.quantity, Quantity::KineticEnergy | Quantity::StrainEnergy)
            })
        }) {
            self.update_energies()?;
        }
        for (r, o) in vr.iter().zip(out.iter_mut()) {
            *o = self.value(*r, VarType::Real)?;
        }
        Ok(())
    }

    /// fmi2GetInteger.
    pub fn get_integer(&mut self, vr: &[u32], out: &mut [i32]) -> FmiResult<()> {
        self.prepare_get("fmi2GetInteger")?;
        for (r, o) in vr.iter().zip(out.iter_mut()) {
            *o = self.value(*r, VarType::Integer)?.min(i32::MAX as f64) as i32;
        }
        Ok(())
    }

    /// fmi2GetBoolean / fmi2GetString: this FMU has no such variables.
    pub fn get_none(&mut self, function: &str, kind: &str, vr: &[u32]) -> FmiResult<()> {
        self.require(function, &Self::GET_MODES)?;
        match vr.first() {
            None => Ok(()),
            Some(r) => Err(FmiError::Invalid(format!(
                "unknown value reference {r}: this FMU has no {kind} variables"
            ))),
        }
    }

    const SET_MODES: [Mode; 3] = [
        Mode::Instantiated,
        Mode::InitializationMode,
        Mode::StepComplete,
    ];

    /// Checks that variable `r` may be set now (not an output, a parameter only before
    /// fmi2ExitInitializationMode).
    fn settable(&self, r: u32, ty: VarType) -> FmiResult<&Variable> {
        let v = self.var(r, ty)?;
        match v.causality {
            Causality::Output => Err(FmiError::Invalid(format!(
                "'{}' (value reference {r}) is an output and cannot be set",
                v.name
            ))),
            Causality::Parameter if self.mode == Mode::StepComplete => {
                Err(FmiError::Invalid(format!(
                    "'{}' (value reference {r}) is a fixed parameter: it can be set only before \
                     fmi2ExitInitializationMode",
                    v.name
                )))
            }
            _ => Ok(v),
        }
    }

    /// fmi2SetReal: checks every value first and applies none if one is bad. Inputs take effect
    /// at the next doStep.
    pub fn set_real(&mut self, vr: &[u32], values: &[f64]) -> FmiResult<()> {
        self.require("fmi2SetReal", &Self::SET_MODES)?;
        for (&r, &x) in vr.iter().zip(values) {
            let v = self.settable(r, VarType::Real)?;
            if !x.is_finite() {
                return Err(FmiError::Invalid(format!(
                    "'{}' (value reference {r}) cannot be set to {}: values must be finite (nothing was set)",
                    v.name,
                    num(x)
                )));
            }
            if v.causality == Causality::Parameter {
                let mut probe = self.params.clone();
                VariableTable::set_parameter(&mut probe, v.quantity, x).map_err(|m| {
                    FmiError::Invalid(format!(
                        "'{}' cannot be set to {}: {m} (nothing was set)",
                        v.name,
                        num(x)
                    ))
                })?;
            }
        }
        for (&r, &x) in vr.iter().zip(values) {
            let q = self.table.vars[r as usize].quantity;
            match q {
                Quantity::Gravity(k) => {
                    if self.inputs.gravity_source == GravitySource::Scene
                        && x != self.inputs.gravity[k]
                        && !self.gravity_ignored_warned
                    {
                        self.gravity_ignored_warned = true;
                        self.log.warn(format!(
                            "fmi2SetReal: gravity_{} set to {} while gravity_source = 1 (the \
                             scene's gravity law): the gravity inputs are ignored; set the \
                             parameter gravity_source = 2 to drive gravity from the inputs",
                            ["x", "y", "z"][k],
                            num(x)
                        ));
                    }
                    self.inputs.gravity[k] = x;
                }
                Quantity::GroupDisplacement(g, k) => self.inputs.displacement[g][k] = x,
                Quantity::Load(l, k) => self.inputs.load[l][k] = x,
                _ => {
                    VariableTable::set_parameter(&mut self.params, q, x)
                        .map_err(FmiError::Invalid)?;
                    self.stale = true;
                }
            }
        }
        Ok(())
    }

    /// fmi2SetInteger: the Integer parameters gravity_source and boundary_input_timing.
    pub fn set_integer(&mut self, vr: &[u32], values: &[i32]) -> FmiResult<()> {
        self.require("fmi2SetInteger", &Self::SET_MODES)?;
        let mut gravity = self.inputs.gravity_source;
        let mut timing = self.inputs.boundary_timing;
        for (&r, &x) in vr.iter().zip(values) {
            let v = self.settable(r, VarType::Integer)?;
            let bad = || {
                FmiError::Invalid(format!(
                    "'{}' (value reference {r}) cannot be set to {x}: allowed values are 1 and 2 \
                     (nothing was set)",
                    v.name
                ))
            };
            match v.quantity {
                Quantity::GravitySource => gravity = GravitySource::from_int(x).ok_or_else(bad)?,
                Quantity::BoundaryTiming => timing = BoundaryTiming::from_int(x).ok_or_else(bad)?,
                _ => {
                    return Err(FmiError::Invalid(format!(
                        "'{}' (value reference {r}) cannot be set",
                        v.name
                    )))
                }
            }
        }
        if gravity != self.inputs.gravity_source {
            self.log
                .event(&format!("gravity_source = {}", gravity as i32));
            self.gravity_ignored_warned = false;
        }
        self.inputs.gravity_source = gravity;
        self.inputs.boundary_timing = timing;
        Ok(())
    }

    /// fmi2SetBoolean / fmi2SetString: this FMU has no such variables.
    pub fn set_none(&mut self, function: &str, kind: &str, vr: &[u32]) -> FmiResult<()> {
        self.require(function, &Self::SET_MODES)?;
        match vr.first() {
            None => Ok(()),
            Some(r) => Err(FmiError::Invalid(format!(
                "unknown value reference {r}: this FMU has no {kind} variables"
            ))),
        }
    }

    /// fmi2SetRealInputDerivatives: first derivatives of the Real inputs for the next doStep
    /// (canInterpolateInputs): over the step an input is `u + du/dt (tau - t)`. They apply to
    /// that one step and are cleared after it.
    pub fn set_real_input_derivatives(
        &mut self,
        vr: &[u32],
        order: &[i32],
        values: &[f64],
    ) -> FmiResult<()> {
        // FMI 2.0 (section 4.2.4, the co-simulation state machine) allows input derivatives
        // from instantiation on: they apply to the first step like any later one.
        self.require(
            "fmi2SetRealInputDerivatives",
            &[
                Mode::Instantiated,
                Mode::InitializationMode,
                Mode::StepComplete,
            ],
        )?;
        for ((&r, &o), &x) in vr.iter().zip(order).zip(values) {
            let v = self.var(r, VarType::Real)?;
            if v.causality != Causality::Input {
                return Err(FmiError::Invalid(format!(
                    "'{}' (value reference {r}) is not an input: only inputs have derivatives",
                    v.name
                )));
            }
            if o != 1 {
                return Err(FmiError::Invalid(format!(
                    "derivative order {o} of '{}': only first derivatives are used \
                     (linear interpolation over the step; nothing was set)",
                    v.name
                )));
            }
            if !x.is_finite() {
                return Err(FmiError::Invalid(format!(
                    "the derivative of '{}' cannot be {}: values must be finite (nothing was set)",
                    v.name,
                    num(x)
                )));
            }
        }
        for (&r, &x) in vr.iter().zip(values) {
            match self.table.vars[r as usize].quantity {
                Quantity::Gravity(k) => self.inputs.gravity_rate[k] = x,
                Quantity::GroupDisplacement(g, k) => self.inputs.displacement_rate[g][k] = x,
                Quantity::Load(l, k) => self.inputs.load_rate[l][k] = x,
                _ => {}
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_support::small2d;
    use crate::sim::Simulation;

    #[test]
    fn non_finite_energies_are_errors_not_stale_values() {
        // Issue 8.10: a NaN energy was handed out as the last finite value with fmi2OK.
        let mut i = small2d();
        let ke = i.table().by_name("kinetic_energy").unwrap().value_reference;
        let mut out = [0.0];
        i.get_real(&[ke], &mut out).unwrap();
        assert!(out[0].is_finite());
        // (A state with a NaN is refused on restore: poke the model directly.)
        match i.sim.as_mut().unwrap() {
            Simulation::D2(m) => m.world.p.v[7][1] = f64::NAN,
            Simulation::D3(m) => m.world.p.v[7][1] = f64::NAN,
        }
        i.energies_fresh = false;
        let e = i.get_real(&[ke], &mut out).unwrap_err();
        assert!(
            e.message().contains("kinetic_energy is NaN"),
            "{}",
            e.message()
        );
    }
}
