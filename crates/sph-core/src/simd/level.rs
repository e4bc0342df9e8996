//! Which vector instructions the SIMD code uses: the best this
//! CPU has (detected once at run time), or a lower level named by the
//! `SPH_SIMD` environment variable. Every level gives bitwise the same results,
//! so the variable changes only the speed: it is there to measure the paths
//! side by side on one machine and to check that they agree.

use std::sync::OnceLock;

/// A set of vector instructions the inner loops are written for.
///
/// Ordered from the least to the most capable. More levels may come (other
/// architectures), so a match on it outside this crate needs a `_` arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[non_exhaustive]
pub enum Simd {
    /// What every CPU of the target has: SSE2 on x86-64 (the eight lanes in
    /// two registers), plain arrays elsewhere.
    Baseline,
    /// AVX2 (and POPCNT) on x86-64: the eight lanes in one register (most
    /// desktop CPUs since 2013).
    Avx2,
    /// AVX-512F on x86-64: the AVX2 lanes compiled with AVX-512VL's 32
    /// registers, and the neighbour scan's own 16-lane path.
    Avx512,
}

impl Simd {
    /// The level's name as `SPH_SIMD` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Simd::Baseline => "baseline",
            Simd::Avx2 => "avx2",
            Simd::Avx512 => "avx512",
        }
    }

    /// The best level this CPU supports, whatever `SPH_SIMD` says.
    pub fn detect() -> Simd {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            // `SPH_SIMD=avx2` takes the AVX2 path on such a CPU, so the AVX-512
            // level needs AVX2 too (every AVX-512 CPU has it; a VM could hide it).
            // AVX-512F also implies FMA and F16C to the compiler.
            if has!("avx512f") && has!("avx2") && has!("popcnt") && has!("fma") && has!("f16c") {
                return Simd::Avx512;
            }
            if has!("avx2") && has!("popcnt") {
                return Simd::Avx2;
            }
        }
        Simd::Baseline
    }
}

/// The level every SIMD path uses: [`Simd::detect`], lowered to `SPH_SIMD` when that
/// is set to `baseline`, `avx2` or `avx512`. Read once per process; an
/// unknown value, or a level above the CPU's (not taken), is reported on
/// stderr once and ignored.
pub fn simd_level() -> Simd {
    static LEVEL: OnceLock<Simd> = OnceLock::new();
    *LEVEL.get_or_init(|| {
        let best = Simd::detect();
        let Some(value) = std::env::var_os("SPH_SIMD") else {
            return best;
        };
        let name = value.to_str().map(|v| v.trim().to_ascii_lowercase());
        match [Simd::Baseline, Simd::Avx2, Simd::Avx512]
            .into_iter()
            .find(|l| name.as_deref() == Some(l.name()))
        {
            Some(asked) if asked > best => {
                eprintln!(
                    "sph-core: SPH_SIMD={value:?} is above this CPU's best; using {}",
                    best.name()
                );
                best
            }
            Some(asked) => asked,
            None => {
                eprintln!(
                    "sph-core: SPH_SIMD={value:?} is not baseline, avx2 or avx512; using {}",
                    best.name()
                );
                best
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_level_never_exceeds_the_cpu() {
        assert!(simd_level() <= Simd::detect());
        assert!(Simd::Baseline < Simd::Avx2 && Simd::Avx2 < Simd::Avx512);
        assert_eq!(Simd::Avx2.name(), "avx2");
    }
}
