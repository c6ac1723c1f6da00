//! The element-wise mean of the float parameters of several modules of one architecture:
//! stochastic weight averaging (Izmailov et al., "Averaging Weights Leads to Wider Optima and
//! Better Generalization", 2018) over checkpoints of one training run. Late checkpoints of a run
//! lie in one basin, so their mean is a network of its own that behaves like their average
//! behaviour; one checkpoint's long-tail rates swing by tens of points between neighbouring
//! updates (experiments/recipe/checkpoint_spread/).
//!
//! burn has no "zip two modules" operation, so this is a visitor (sum every parameter, in
//! visiting order, named by its path) and a mapper (replace each parameter by its mean).

use burn::module::{Module, ModuleMapper, ModuleVisitor, Param};
use burn::tensor::{Tensor, TensorData};

/// One float parameter: its path in the module, shape and running sum.
struct Slot {
    path: String,
    shape: Vec<usize>,
    sum: Vec<f64>,
}

/// Adds every float parameter of a module into `slots` (created by the first module visited).
struct Accumulate<'a> {
    path: Vec<String>,
    slots: &'a mut Vec<Slot>,
    next: usize,
    first: bool,
    problem: Option<String>,
}

impl ModuleVisitor for Accumulate<'_> {
    fn enter_module(&mut self, name: &str, _container_type: &str) {
        self.path.push(name.to_string());
    }

    fn exit_module(&mut self, _name: &str, _container_type: &str) {
        self.path.pop();
    }

    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if self.problem.is_some() {
            return;
        }
        let path = self.path.join(".");
        let tensor = param.val();
        let shape = tensor.shape().dims::<D>().to_vec();
        let values = match tensor.into_data().convert::<f32>().try_into_vec::<f32>() {
            Ok(values) => values,
            Err(e) => {
                self.problem = Some(format!("parameter `{path}`: {e:?}"));
                return;
            }
        };
        if self.first {
            self.slots.push(Slot {
                path,
                shape,
                sum: values.iter().map(|&v| f64::from(v)).collect(),
            });
            return;
        }
        let Some(slot) = self.slots.get_mut(self.next) else {
            self.problem = Some(format!(
                "parameter `{path}` has no counterpart in the first"
            ));
            return;
        };
        self.next += 1;
        if slot.path != path || slot.shape != shape {
            self.problem = Some(format!(
                "parameter `{path}` {shape:?} where the first has `{}` {:?}",
                slot.path, slot.shape
            ));
            return;
        }
        for (sum, v) in slot.sum.iter_mut().zip(values) {
            *sum += f64::from(v);
        }
    }
}

/// Replaces every float parameter by its slot's sum divided by `count`.
struct ReplaceByMean<'a> {
    slots: &'a [Slot],
    next: usize,
    count: f64,
}

impl ModuleMapper for ReplaceByMean<'_> {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let slot = &self.slots[self.next];
        self.next += 1;
        let mean: Vec<f32> = slot.sum.iter().map(|s| (s / self.count) as f32).collect();
        param.map(|tensor| {
            let device = tensor.device();
            Tensor::from_data(TensorData::new(mean, slot.shape.clone()), &device)
        })
    }
}

/// The module whose every float parameter is the mean of that parameter over `modules` (all of
/// one architecture; the first's non-float state is kept). Refuses an empty list and modules
/// whose parameters differ in name, shape or number, saying which.
pub fn average_parameters<M: Module>(modules: Vec<M>) -> Result<M, String> {
    let count = modules.len();
    let mut modules = modules.into_iter();
    let first = modules.next().ok_or("no modules to average")?;
    let mut slots = Vec::new();
    let visit = |module: &M, index: usize, slots: &mut Vec<Slot>| {
        let mut acc = Accumulate {
            path: Vec::new(),
            slots,
            next: 0,
            first: index == 0,
            problem: None,
        };
        module.visit(&mut acc);
        let complete = acc.first || acc.next == acc.slots.len();
        match (acc.problem, complete) {
            (Some(problem), _) => Err(format!("module {}: {problem}", index + 1)),
            (None, false) => Err(format!(
                "module {}: {} parameters where the first has {}",
                index + 1,
                acc.next,
                acc.slots.len()
            )),
            (None, true) => Ok(()),
        }
    };
    visit(&first, 0, &mut slots)?;
    for (index, module) in modules.enumerate() {
        visit(&module, index + 1, &mut slots)?;
    }
    let mut mapper = ReplaceByMean {
        slots: &slots,
        next: 0,
        count: count as f64,
    };
    Ok(first.map(&mut mapper))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{ModelConfig, PolicyNetwork};

    fn first_values(module: &PolicyNetwork) -> Vec<Vec<f32>> {
        struct Values(Vec<Vec<f32>>);
        impl ModuleVisitor for Values {
            fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
                self.0.push(
                    param
                        .val()
                        .into_data()
                        .convert::<f32>()
                        .try_to_vec()
                        .unwrap(),
                );
            }
        }
        let mut values = Values(Vec::new());
        module.visit(&mut values);
        values.0
    }

    fn device() -> burn::prelude::Device {
        crate::backend::Backend::NdArray.device(false).unwrap()
    }

    #[test]
    fn every_parameter_is_the_element_wise_mean() {
        let device = device();
        let config = ModelConfig::small();
        let nets: Vec<PolicyNetwork> = (0..3)
            .map(|seed| {
                device.seed(seed);
                PolicyNetwork::new(&config, &device)
            })
            .collect();
        let each: Vec<Vec<Vec<f32>>> = nets.iter().map(first_values).collect();
        assert_ne!(each[0], each[1], "different seeds give different networks");
        let mean = first_values(&average_parameters(nets).unwrap());
        assert_eq!(mean.len(), each[0].len());
        for (p, param) in mean.iter().enumerate() {
            for (i, value) in param.iter().enumerate() {
                let expected = (each[0][p][i] + each[1][p][i] + each[2][p][i]) / 3.0;
                assert!((value - expected).abs() < 1e-6, "param {p}[{i}]");
            }
        }
    }

    #[test]
    fn the_mean_of_one_module_is_itself() {
        let device = device();
        let net = PolicyNetwork::new(&ModelConfig::small(), &device);
        let before = first_values(&net);
        assert_eq!(
            first_values(&average_parameters(vec![net]).unwrap()),
            before
        );
    }

    #[test]
    fn refuses_nothing_and_different_architectures() {
        assert!(average_parameters::<PolicyNetwork>(Vec::new()).is_err());
        let device = device();
        let small = PolicyNetwork::new(&ModelConfig::small(), &device);
        let wider = ModelConfig {
            hidden: ModelConfig::small().hidden * 2,
            ..ModelConfig::small()
        };
        let e = average_parameters(vec![small, PolicyNetwork::new(&wider, &device)]).unwrap_err();
        assert!(e.starts_with("module 2: parameter `"), "{e}");
    }
}
