//! Which micro-kernel this CPU runs: AVX-512, AVX2 with FMA, or the portable
//! scalar loop. All three compute the same bits (see the crate's promise); the
//! choice changes only the speed.
//!
//! `MRDRIVE_KERNEL=scalar|avx2|avx512` forces one (a kernel the CPU lacks falls
//! back to the best it has), for tests and for measuring one against another.

use std::sync::OnceLock;

/// An instruction set a micro-kernel is written for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Isa {
    /// Plain Rust: `f32::mul_add` in loops (fused on every target; slow without FMA).
    Scalar,
    /// 256-bit vectors with fused multiply-add (x86-64-v3).
    Avx2,
    /// 512-bit vectors (x86-64-v4).
    Avx512,
}

impl Isa {
    /// The widest kernel this CPU can run.
    pub fn best() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Isa::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                return Isa::Avx2;
            }
        }
        Isa::Scalar
    }

    /// The kernels this CPU can run, narrowest first.
    pub fn available() -> Vec<Isa> {
        [Isa::Scalar, Isa::Avx2, Isa::Avx512]
            .into_iter()
            .filter(|&i| i <= Isa::best())
            .collect()
    }

    /// Its name, as `MRDRIVE_KERNEL` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Scalar => "scalar",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// The kernel in use: [`Isa::best`], or what `MRDRIVE_KERNEL` asks for where the
    /// CPU has it (decided once per process).
    pub fn current() -> Isa {
        static CURRENT: OnceLock<Isa> = OnceLock::new();
        *CURRENT.get_or_init(|| {
            let asked = std::env::var("MRDRIVE_KERNEL").ok();
            let asked = match asked.as_deref() {
                Some("scalar") => Isa::Scalar,
                Some("avx2") => Isa::Avx2,
                _ => Isa::Avx512,
            };
            asked.min(Isa::best())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_current_kernel_is_one_the_cpu_has() {
        assert!(Isa::available().contains(&Isa::current()));
        assert_eq!(Isa::available()[0], Isa::Scalar);
        assert_eq!(*Isa::available().last().unwrap(), Isa::best());
    }
}
