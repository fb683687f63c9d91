//! A bank of BatchNorms: one branch per input scale, exactly one used per forward.
//!
//! The paper's resolution-aware BN (docs/protocol.md §6): convolutions are shared across
//! scales, normalisation statistics and affine parameters are per scale. With a
//! single branch the bank is an ordinary BatchNorm (the NRA model).

use burn::module::{Module, Param, RunningState};
use burn::nn::{BatchNorm, BatchNormConfig};
use burn::prelude::*;

/// Configuration of a [`BnBank`].
#[derive(Config, Debug)]
pub struct BnBankConfig {
    /// Channels normalised.
    pub num_features: usize,
    /// Number of branches (scales).
    pub num_branches: usize,
}

impl BnBankConfig {
    /// Builds the bank with fresh (identity) BatchNorms.
    pub fn init(&self, device: &Device) -> BnBank {
        assert!(self.num_branches > 0, "a BN bank needs at least one branch");
        BnBank {
            branches: (0..self.num_branches)
                .map(|_| BatchNormConfig::new(self.num_features).init(device))
                .collect(),
        }
    }
}

/// One BatchNorm2d per scale; `forward` uses the branch it is given.
#[derive(Module, Debug)]
pub struct BnBank {
    /// The branches, in the order of the model's scale set R.
    pub branches: Vec<BatchNorm>,
}

impl BnBank {
    /// Normalises with branch `branch` only (panics if out of range: branches are chosen by the model).
    pub fn forward(&self, x: Tensor<4>, branch: usize) -> Tensor<4> {
        crate::batch_norm::batch_norm(&self.branches[branch], x)
    }

    /// Number of branches.
    pub fn num_branches(&self) -> usize {
        self.branches.len()
    }

    /// A bank of `n` branches, each an independent copy of branch `from` of `self`.
    ///
    /// Copies are deep: new parameter ids and new running-state cells, so
    /// training one branch never moves another.
    pub fn replicate(&self, from: usize, n: usize) -> BnBank {
        BnBank {
            branches: (0..n).map(|_| copy_bn(&self.branches[from])).collect(),
        }
    }

    /// Sets the running-statistics momentum of every branch (1 / (k + 1) gives a cumulative mean).
    pub fn set_momentum(&mut self, momentum: f64) {
        for bn in &mut self.branches {
            bn.momentum = momentum;
        }
    }

    /// Folds pending running-statistics updates into every branch's value.
    ///
    /// burn's `RunningState::value` may lag one update behind; `valid()` and
    /// copies read it, so call this after training forwards.
    pub fn sync(&self) {
        for bn in &self.branches {
            let _ = bn.running_mean.value_sync();
            let _ = bn.running_var.value_sync();
        }
    }

    /// Resets the running statistics of branch `branch` to mean 0, variance 1.
    pub fn reset_running_stats(&mut self, branch: usize) {
        let bn = &mut self.branches[branch];
        let mean = bn.running_mean.value_sync();
        let var = bn.running_var.value_sync();
        bn.running_mean = RunningState::new(mean.zeros_like());
        bn.running_var = RunningState::new(var.ones_like());
    }
}

/// A deep copy of a BatchNorm: same values, new parameter ids and running-state cells.
pub fn copy_bn(bn: &BatchNorm) -> BatchNorm {
    BatchNorm {
        gamma: Param::from_tensor(bn.gamma.val().detach()),
        beta: Param::from_tensor(bn.beta.val().detach()),
        training: Param::from_bool(bn.training.is_enabled()),
        running_mean: RunningState::new(bn.running_mean.value_sync()),
        running_var: RunningState::new(bn.running_var.value_sync()),
        momentum: bn.momentum,
        epsilon: bn.epsilon,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(t: Tensor<1>) -> Vec<f32> {
        t.into_data().try_to_vec::<f32>().unwrap()
    }

    #[test]
    fn training_at_one_branch_moves_only_its_statistics() {
        let device = Device::flex().autodiff();
        device.seed(1);
        let bank = BnBankConfig::new(3, 2).init(&device);
        let x = Tensor::<4>::random(
            [4, 3, 5, 5],
            burn::tensor::Distribution::Normal(2.0, 1.0),
            &device,
        );
        let _ = bank.forward(x, 1);
        assert_eq!(
            data(bank.branches[0].running_mean.value_sync()),
            vec![0.0; 3]
        );
        assert_eq!(
            data(bank.branches[0].running_var.value_sync()),
            vec![1.0; 3]
        );
        assert!(
            data(bank.branches[1].running_mean.value_sync())
                .iter()
                .all(|m| *m > 0.1)
        );
    }

    #[test]
    fn replicas_are_independent_copies() {
        let device = Device::flex().autodiff();
        device.seed(2);
        let one = BnBankConfig::new(2, 1).init(&device);
        let x = Tensor::<4>::random(
            [4, 2, 3, 3],
            burn::tensor::Distribution::Normal(1.0, 1.0),
            &device,
        );
        let _ = one.forward(x.clone(), 0);
        let two = one.replicate(0, 2);
        assert_eq!(
            data(two.branches[1].running_mean.value_sync()),
            data(one.branches[0].running_mean.value_sync())
        );
        let _ = two.forward(x.mul_scalar(5.0), 0);
        assert_ne!(
            data(two.branches[0].running_mean.value_sync()),
            data(two.branches[1].running_mean.value_sync())
        );
        assert_ne!(two.branches[0].gamma.id, two.branches[1].gamma.id);
    }
}
