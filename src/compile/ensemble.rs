//! Ensembles: many initial conditions integrated in parallel.
//!
//! The integrator is any closure from an initial state to a final state (or an error), so
//! this module depends on no integrator's types: the caller decides the method, step and span.

use rayon::prelude::*;

/// Why an ensemble could not run.
#[derive(Debug, thiserror::Error)]
pub enum EnsembleError {
    /// `initial` is not a whole number of states.
    #[error("{len} initial values do not split into states of dimension {dim}")]
    Shape { len: usize, dim: usize },
    /// The thread pool could not be built.
    #[error("could not start {threads} worker threads: {reason}")]
    Pool { threads: usize, reason: String },
}

/// Integrates every initial state in `initial` (consecutive states of `dim` values each) with
/// `integrate`, in parallel on rayon's global pool. Results keep the order of the states; one
/// trajectory's failure does not stop the others.
pub fn ensemble<E, F>(initial: &[f64], dim: usize, integrate: F) -> Result<Vec<Result<Vec<f64>, E>>, EnsembleError>
where
    E: Send,
    F: Fn(&[f64]) -> Result<Vec<f64>, E> + Sync,
{
    if dim == 0 || initial.len() % dim != 0 {
        return Err(EnsembleError::Shape { len: initial.len(), dim });
    }
    Ok(initial.par_chunks(dim).map(&integrate).collect())
}

/// [`ensemble`] on a pool of exactly `threads` workers (for scaling measurements).
pub fn ensemble_with_threads<E, F>(
    threads: usize,
    initial: &[f64],
    dim: usize,
    integrate: F,
) -> Result<Vec<Result<Vec<f64>, E>>, EnsembleError>
where
    E: Send,
    F: Fn(&[f64]) -> Result<Vec<f64>, E> + Sync + Send,
{
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| EnsembleError::Pool { threads, reason: e.to_string() })?;
    pool.install(|| ensemble(initial, dim, integrate))
}

/// How many `f64` lanes one SIMD register holds on this host, found at run time so one
/// binary picks the widest batch the CPU executes: 8 with AVX-512, 4 with AVX2, 2 with SSE2
/// (baseline on x86-64) or NEON, 1 elsewhere. A batch integrator sizes its batches by this.
pub fn simd_lanes() -> usize {
    #[cfg(target_arch = "x86_64")]
    let lanes = if std::arch::is_x86_feature_detected!("avx512f") {
        8
    } else if std::arch::is_x86_feature_detected!("avx2") {
        4
    } else {
        2
    };
    #[cfg(target_arch = "aarch64")]
    let lanes = 2;
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    let lanes = 1;
    lanes
}
