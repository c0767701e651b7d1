//! The binding's derivation cache: the symbolic results that compiling needs (`W q'' = F` of
//! a Lagrangian, the Hamiltonian by the Legendre transform) are kept in the engine's
//! derivation cache ([`lagrangian::cache::Cache`]), in memory for the process and on
//! disk in the directory the command line uses (`$LAGRANGIAN_CACHE_DIR`, `off` for none,
//! else `$XDG_CACHE_HOME/lagrangian` or `~/.cache/lagrangian`).
//!
//! Why: a Dask sweep unpickles the system from its text in every worker process, and a
//! parameter grid makes a new `System` per parameter row. Without this cache each of them
//! derived the equations again; with it a machine derives a system once, and every other
//! process (and every later session) loads the printed result, which the engine re-parses and
//! checks. Entries are keyed by symbolic content only (the Lagrangian, forces, dissipation,
//! coordinates, assumptions), not by parameter values, which are bound at compile time.
//!
//! The entries name this extension module's file (size and modification time) as the engine
//! build, not the running executable, which is the Python interpreter here: a rebuilt
//! extension never reads the entries of another build.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

use lagrangian::cache::{configured_dir, Cache, Step};
use lagrangian::mechanics::{Kind, MechanicsError, System};
use lagrangian::Expr;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The process's cache and the directory it was made for.
struct State {
    cache: Cache,
    dir: Option<PathBuf>,
}

static STATE: Mutex<Option<State>> = Mutex::new(None);
static BUILD: OnceLock<String> = OnceLock::new();
static DERIVED: AtomicUsize = AtomicUsize::new(0);
static HITS: AtomicUsize = AtomicUsize::new(0);

/// What this build calls itself in on-disk keys: the extension module's file.
fn build(py: Python<'_>) -> String {
    BUILD
        .get_or_init(|| {
            let file: Option<String> =
                py.import("lagrangian._core").and_then(|m| m.getattr("__file__")?.extract()).ok();
            let meta = file.as_ref().and_then(|f| std::fs::metadata(f).ok());
            match meta {
                Some(m) => {
                    let modified = m
                        .modified()
                        .ok()
                        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                        .map_or(0, |d| d.as_nanos());
                    format!("python extension, {} bytes, modified {modified}", m.len())
                }
                // Unknown build: a key no other build shares, so nothing stale is ever read.
                None => format!("python extension, unknown build, process {}", std::process::id()),
            }
        })
        .clone()
}

fn new_state(py: Python<'_>, dir: Option<PathBuf>) -> State {
    let cache = match &dir {
        Some(d) => Cache::with_dir(d).for_build(build(py)),
        None => Cache::new(),
    };
    State { cache, dir }
}

/// Makes sure the cache exists (it needs the GIL once, to name the build).
pub fn init(py: Python<'_>) {
    let mut s = STATE.lock().unwrap_or_else(|e| e.into_inner());
    if s.is_none() {
        *s = Some(new_state(py, configured_dir()));
    }
}

fn with_cache<R>(f: impl FnOnce(&mut Cache) -> R) -> Option<R> {
    let mut s = STATE.lock().unwrap_or_else(|e| e.into_inner());
    s.as_mut().map(|s| f(&mut s.cache))
}

/// Looks `what` up, or derives it with `derive` (outside the lock) and keeps it.
fn cached<E>(
    sys: &System,
    step: Step,
    what: &str,
    inputs: &[Expr],
    derive: impl FnOnce() -> Result<Vec<Expr>, E>,
) -> Result<Vec<Expr>, E> {
    let coords = sys.coordinates();
    let decls = sys.declarations();
    if let Some(v) = with_cache(|c| c.load_exprs(step, what, coords, inputs, decls)).flatten() {
        HITS.fetch_add(1, Ordering::Relaxed);
        return Ok(v);
    }
    let v = derive()?;
    DERIVED.fetch_add(1, Ordering::Relaxed);
    with_cache(|c| c.store_exprs(step, what, coords, inputs, v.clone()));
    Ok(v)
}

/// `W q'' = F` of `sys` (forces and dissipation included), from the cache when an earlier
/// process derived it. A cached entry of the wrong shape is derived again.
pub fn mass_matrix(sys: &System) -> Result<(Vec<Vec<Expr>>, Vec<Expr>), MechanicsError> {
    let n = sys.coordinates().len();
    let Some(l) = sys.lagrangian() else { return sys.mass_matrix_split() };
    let mut inputs = vec![l.clone()];
    inputs.extend(sys.forces().iter().cloned());
    inputs.push(sys.rayleigh().cloned().unwrap_or_else(Expr::zero));
    let flat = cached(sys, Step::EulerLagrange, "python: W q'' = F, forces, Rayleigh", &inputs, || {
        let (w, f) = sys.mass_matrix_split()?;
        Ok::<_, MechanicsError>(w.into_iter().flatten().chain(f).collect())
    })?;
    if flat.len() != n * n + n {
        return sys.mass_matrix_split();
    }
    let w = flat[..n * n].chunks(n).map(<[Expr]>::to_vec).collect();
    Ok((w, flat[n * n..].to_vec()))
}

/// `H` of `sys`: its own, or the Legendre transform of `L` (from the cache when derived before).
pub fn hamiltonian(sys: &System) -> Result<Expr, MechanicsError> {
    let l = match sys.kind() {
        Kind::Hamiltonian(h) => return Ok(h.clone()),
        Kind::Lagrangian(l) => l,
    };
    // The cache is keyed by L alone: the refusal must come before a hit for the same L.
    sys.refuse_velocity_constraints("the Hamiltonian (and everything derived from H)")?;
    let v = cached(sys, Step::Legendre, "python: H", std::slice::from_ref(l), || sys.hamiltonian().map(|h| vec![h]))?;
    match v.into_iter().next() {
        Some(h) => Ok(h),
        None => sys.hamiltonian(),
    }
}

#[pyfunction]
pub fn cache_info(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    init(py);
    let dir = STATE.lock().unwrap_or_else(|e| e.into_inner()).as_ref().and_then(|s| s.dir.clone());
    let d = PyDict::new(py);
    d.set_item("dir", dir.map(|p| p.to_string_lossy().into_owned()))?;
    d.set_item("derived", DERIVED.load(Ordering::Relaxed))?;
    d.set_item("hits", HITS.load(Ordering::Relaxed))?;
    Ok(d)
}

/// ``set_cache_dir(path)``: keeps derivations in ``path`` from now on (``None``: in memory
/// only). The in-memory part starts empty. The default is the command line's directory.
#[pyfunction]
#[pyo3(signature = (path))]
pub fn set_cache_dir(py: Python<'_>, path: Option<PathBuf>) {
    let state = new_state(py, path);
    *STATE.lock().unwrap_or_else(|e| e.into_inner()) = Some(state);
}
