//! The derivation cache, keyed by symbolic content: in memory for one session (a REPL keeps it
//! across `load`), and optionally on disk, so that a second `lagrangian run` of a scene whose
//! numbers changed reuses the first run's derivations.
//!
//! An on-disk entry is one JSON file named by a stable 128-bit hash of the key's text. The key
//! text is the plain printed form of everything the result depends on (the kind of derivation,
//! the coordinates, the declared functions and positive symbols, the input expressions, a
//! format version and the engine build) and is stored in the entry too: a load compares it in full, so a hash
//! collision is a miss, never a wrong answer. Results are stored as plain text, which the
//! printer guarantees re-parses to the identical expression; a load re-parses each expression
//! and re-prints it, and any difference (a corrupt, truncated, hand-edited or foreign-version
//! file) makes the entry a miss that is rebuilt and rewritten. Each entry also carries a
//! checksum of its value, so a well-formed entry whose value was edited (it still re-parses)
//! is a miss too; entries that are not regular files (links, devices) or are over
//! [`MAX_ENTRY_BYTES`] are ignored unread. Nothing here is ever an error:
//! a cache that cannot be read or written only costs the time of building again.

use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use serde_json::{json, Value as Json};

use crate::expr::{Expr, Symbol};
use crate::parse::{parse_with, Declarations};
use crate::print::plain;
use crate::report::Line;

/// One kind of work the plan reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Step {
    /// Euler–Lagrange equations.
    EulerLagrange,
    /// Legendre transform.
    Legendre,
    /// Hamilton's equations.
    Hamilton,
    /// Conserved quantities.
    Conserved,
    /// A Poisson bracket.
    Bracket,
    /// The energy function.
    Energy,
    /// The accelerations `q'' = …` (and the multipliers of constraints).
    Accelerations,
    /// Canonical momenta `p = ∂L/∂q'` (for initial states and plots).
    Momenta,
    /// The split `H = T(p) + V(q)`.
    Split,
    /// A compiled right-hand side.
    Compile,
    /// An integration.
    Integrate,
}

impl Step {
    /// A short name for the plan.
    pub fn name(self) -> &'static str {
        match self {
            Step::EulerLagrange => "Euler–Lagrange equations",
            Step::Legendre => "Legendre transform",
            Step::Hamilton => "Hamilton's equations",
            Step::Conserved => "conserved quantities",
            Step::Bracket => "Poisson bracket",
            Step::Energy => "energy function",
            Step::Accelerations => "accelerations",
            Step::Momenta => "canonical momenta",
            Step::Split => "separable split H = T(p) + V(q)",
            Step::Compile => "compiled right-hand side",
            Step::Integrate => "integration",
        }
    }
}

/// The on-disk format; entries of another version are ignored. (2: entries carry a checksum
/// of their value; 3: derivation lines may be lines of text.)
pub const CACHE_FORMAT: u32 = 3;

/// The largest cache entry read, in bytes; a larger file is a miss, like a damaged one.
pub const MAX_ENTRY_BYTES: u64 = 64 << 20;

/// The bytes of an entry, if it is a regular file (not a symbolic link, a device or a pipe:
/// an entry linked to `/dev/zero` would otherwise be read forever) of at most
/// [`MAX_ENTRY_BYTES`].
fn read_entry(path: &Path) -> Option<Vec<u8>> {
    use std::io::Read;
    let meta = std::fs::symlink_metadata(path).ok()?;
    if !meta.is_file() || meta.len() > MAX_ENTRY_BYTES {
        return None;
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path).ok()?.take(MAX_ENTRY_BYTES + 1).read_to_end(&mut bytes).ok()?;
    (bytes.len() as u64 <= MAX_ENTRY_BYTES).then_some(bytes)
}

/// The checksum stored with an entry's value: FNV-1a 128 of the key text and the value's
/// JSON text. It catches an entry edited by hand or by another program (the key still matches
/// and every expression still re-parses, but the value is not what was derived); it is a
/// checksum, not a signature: whoever can write the cache directory can recompute it.
fn checksum(key: &str, value: &Json) -> String {
    let text = format!("{key}\u{0}{}", serde_json::to_string(value).unwrap_or_default());
    let mut name = file_name(&text);
    name.truncate(32);
    name
}

/// The results a cache holds in memory at most. A REPL, a notebook kernel or a Dask worker lives
/// long and derives system after system; every result held keeps its expressions' nodes alive
/// (about 6 kB a derivation), so an unbounded map grew without end. Past this count the oldest
/// results are dropped (an on-disk cache still has them). A scene needs far fewer.
pub const MAX_IN_MEMORY: usize = 1024;

/// The derivation cache: symbolic results keyed by their symbolic inputs. Keep one alive
/// across runs (the REPL does, and `scene::Session::with_cache` lets
/// callers do it) to reuse work; give it a directory ([`Cache::with_dir`]) to reuse work
/// across processes.
#[derive(Default)]
pub struct Cache {
    map: HashMap<CacheKey, Value>,
    /// The keys of `map`, oldest first: past [`MAX_IN_MEMORY`] the oldest results are dropped.
    order: VecDeque<CacheKey>,
    dir: Option<PathBuf>,
    /// The engine build named in on-disk keys, when not the running executable (see
    /// [`Cache::for_build`]).
    build: Option<String>,
}

/// Everything a derivation depends on. Symbols carry their positivity, so equal keys mean
/// equal assumptions too.
#[derive(Clone, PartialEq, Eq, Hash)]
#[doc(hidden)]
pub struct CacheKey {
    pub step: Step,
    pub coords: Vec<Symbol>,
    pub inputs: Vec<Expr>,
    /// Numbers that are part of the content (compiled code binds parameter values).
    pub numbers: Vec<u64>,
    pub extra: String,
}

impl CacheKey {
    /// The key of a symbolic derivation: it depends on its inputs and coordinates only (no
    /// bound numbers, nothing extra).
    pub fn symbolic(step: Step, coords: &[Symbol], inputs: Vec<Expr>) -> CacheKey {
        CacheKey { step, coords: coords.to_vec(), inputs, numbers: vec![], extra: String::new() }
    }
}

/// A cached result.
#[derive(Clone)]
#[doc(hidden)]
pub enum Value {
    Expr(Expr),
    Lines(Vec<Line>),
    Exprs(Vec<Expr>),
    /// Compiled code lives in memory only (it binds parameter values and holds tapes).
    // Compiled values are cached by scenes only (an engine-only build never constructs them).
    #[cfg_attr(not(feature = "frontends"), allow(dead_code))]
    Compiled(Arc<crate::simulate::Compiled>),
    /// The variational equations of the chaos statements (memory only, like `Compiled`).
    #[cfg_attr(not(feature = "frontends"), allow(dead_code))]
    Variational(Arc<crate::compile::Variational>),
}

impl Cache {
    /// An empty in-memory cache.
    pub fn new() -> Cache {
        Cache::default()
    }

    /// An empty in-memory cache backed by the directory `dir` (created when first written).
    pub fn with_dir(dir: impl Into<PathBuf>) -> Cache {
        Cache { dir: Some(dir.into()), ..Cache::default() }
    }

    /// Names the engine build whose entries this cache reads and writes, in place of the
    /// running executable's size and modification time (the default, see `engine_identity`).
    /// A library loaded into another program needs this: in the Python extension the
    /// executable is the interpreter, which stays the same when the engine is rebuilt, so the
    /// binding names its own module file instead.
    pub fn for_build(mut self, build: impl Into<String>) -> Cache {
        self.build = Some(build.into());
        self
    }

    /// Expressions a library caller outside the scene runner derived by `step` from `inputs`
    /// in the coordinates `coords` (the Python binding keeps `W q'' = F` and the Hamiltonian
    /// this way, so that its Dask workers derive a system once per machine, not once per
    /// process): from memory, else from the disk, re-parsed with `decls` and checked like
    /// every entry. `what` tells apart results of one step (it is part of the key).
    pub fn load_exprs(
        &mut self,
        step: Step,
        what: &str,
        coords: &[Symbol],
        inputs: &[Expr],
        decls: &Declarations,
    ) -> Option<Vec<Expr>> {
        let key = CacheKey { extra: what.to_string(), ..CacheKey::symbolic(step, coords, inputs.to_vec()) };
        match self.get(&key).or_else(|| self.load(&key, decls))? {
            Value::Exprs(v) => Some(v),
            _ => None,
        }
    }

    /// Keeps what [`Cache::load_exprs`] looks up, in memory and (with a directory) on disk.
    pub fn store_exprs(&mut self, step: Step, what: &str, coords: &[Symbol], inputs: &[Expr], value: Vec<Expr>) {
        let key = CacheKey { extra: what.to_string(), ..CacheKey::symbolic(step, coords, inputs.to_vec()) };
        self.insert(key, Value::Exprs(value));
    }

    /// The directory of the on-disk cache, if any.
    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    /// How many results it holds in memory.
    pub fn len(&self) -> usize {
        self.map.len()
    }

    /// Whether it holds nothing in memory.
    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }

    /// A result held in memory.
    #[doc(hidden)]
    pub fn get(&self, key: &CacheKey) -> Option<Value> {
        self.map.get(key).cloned()
    }

    /// A result from the disk, re-parsed with `decls`; it is then held in memory too.
    #[doc(hidden)]
    pub fn load(&mut self, key: &CacheKey, decls: &Declarations) -> Option<Value> {
        let text = disk_key(key, self.build.as_deref())?;
        let path = self.dir.as_ref()?.join(file_name(&text));
        let bytes = read_entry(&path)?;
        let value = decode(&bytes, &text, decls)?;
        self.hold(key.clone(), value.clone());
        Some(value)
    }

    /// Keeps a result in memory, and on disk when it is symbolic and a directory is set.
    #[doc(hidden)]
    pub fn insert(&mut self, key: CacheKey, value: Value) {
        if let (Some(dir), Some(text)) = (&self.dir, disk_key(&key, self.build.as_deref())) {
            if let Some(entry) = encode(&value, &text) {
                // A failed write only means the next run builds again.
                let _ = write_atomically(dir, &file_name(&text), entry.as_bytes());
            }
        }
        self.hold(key, value);
    }

    /// Keeps a result in memory, dropping the oldest past [`MAX_IN_MEMORY`].
    fn hold(&mut self, key: CacheKey, value: Value) {
        if self.map.insert(key.clone(), value).is_none() {
            self.order.push_back(key);
        }
        while self.map.len() > MAX_IN_MEMORY {
            let Some(oldest) = self.order.pop_front() else { break };
            self.map.remove(&oldest);
        }
    }
}

/// The cache directory of the command line and of the library's other front ends:
/// `$LAGRANGIAN_CACHE_DIR` (`off` means none), else [`default_dir`].
pub fn configured_dir() -> Option<PathBuf> {
    match std::env::var_os("LAGRANGIAN_CACHE_DIR").filter(|v| !v.is_empty()) {
        Some(v) if v == "off" => None,
        Some(v) => Some(PathBuf::from(v)),
        None => default_dir(),
    }
}

/// The default cache directory: `$XDG_CACHE_HOME/lagrangian`, else `~/.cache/lagrangian`.
pub fn default_dir() -> Option<PathBuf> {
    let nonempty = |v: std::ffi::OsString| (!v.is_empty()).then(|| PathBuf::from(v));
    if let Some(x) = std::env::var_os("XDG_CACHE_HOME").and_then(nonempty) {
        return Some(x.join("lagrangian"));
    }
    std::env::var_os("HOME").and_then(nonempty).map(|h| h.join(".cache").join("lagrangian"))
}

/// The key as stable text: plain printed forms, one per line, with the format version and the
/// engine build (`build`, else the running executable's). `None` for results that are not
/// kept on disk (compiled code).
#[doc(hidden)]
pub fn disk_key(key: &CacheKey, build: Option<&str>) -> Option<String> {
    if key.step == Step::Compile || !key.numbers.is_empty() {
        return None;
    }
    let mut symbols: Vec<String> = Vec::new();
    let mut s = format!(
        "lagrangian derivation cache, format {CACHE_FORMAT}\nengine: {}\nstep: {:?}\ncoordinates:",
        build.map_or_else(|| engine_identity().to_string(), |b| format!("{} ({b})", env!("CARGO_PKG_VERSION"))),
        key.step
    );
    for q in &key.coords {
        s.push(' ');
        s.push_str(&q.to_string());
    }
    s.push_str("\ninputs:\n");
    for e in &key.inputs {
        s.push_str(&plain(e));
        s.push('\n');
        symbols.extend(e.free_symbols().iter().filter(|x| x.is_positive()).map(|x| x.name().to_string()));
        symbols.extend(e.applied_functions().into_iter().map(|f| format!("{f}()")));
    }
    // Assumptions do not show in the plain form; they are part of the content.
    symbols.sort();
    symbols.dedup();
    s.push_str("assumed positive, and functions: ");
    s.push_str(&symbols.join(" "));
    s.push_str("\nextra: ");
    s.push_str(&key.extra);
    s.push('\n');
    Some(s)
}

/// Which build of the engine derived an entry: the crate version and the size and modification
/// time of the running executable. A rebuilt engine may print a derivation differently (a new
/// simplification, a new canonical order), and an entry it did not write must not make its
/// output differ from a `--no-cache` run; so every rebuild starts a fresh set of entries.
fn engine_identity() -> &'static str {
    static IDENTITY: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    IDENTITY.get_or_init(|| {
        let build = std::env::current_exe()
            .and_then(std::fs::metadata)
            .map(|m| {
                let modified = m
                    .modified()
                    .ok()
                    .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                    .map_or(0, |d| d.as_nanos());
                format!("{} bytes, modified {modified}", m.len())
            })
            .unwrap_or_else(|_| "unknown build".to_string());
        format!("{} ({build})", env!("CARGO_PKG_VERSION"))
    })
}

/// A 128-bit FNV-1a hash of the key text, as 32 hex digits (stable across builds and
/// platforms, unlike `std`'s hasher).
#[doc(hidden)]
pub fn file_name(text: &str) -> String {
    const PRIME: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013B;
    let mut h: u128 = 0x6c62_272e_07bb_0142_62b8_2175_6295_c58d;
    for b in text.bytes() {
        h ^= u128::from(b);
        h = h.wrapping_mul(PRIME);
    }
    format!("{h:032x}.json")
}

fn encode(value: &Value, key: &str) -> Option<String> {
    let line = |l: &Line| match l {
        Line::Equation { label, lhs, rhs, note } => json!({
            "label": label,
            "lhs": lhs_json(lhs),
            "rhs": plain(rhs),
            "note": note,
        }),
        Line::Text(s) => json!({ "text": s }),
    };
    let v = match value {
        Value::Expr(e) => json!({ "expr": plain(e) }),
        Value::Exprs(es) => json!({ "exprs": es.iter().map(plain).collect::<Vec<_>>() }),
        Value::Lines(ls) => json!({ "lines": ls.iter().map(line).collect::<Vec<_>>() }),
        Value::Compiled(_) | Value::Variational(_) => return None,
    };
    let doc = json!({ "format": CACHE_FORMAT, "key": key, "checksum": checksum(key, &v), "value": v });
    serde_json::to_string(&doc).ok()
}

/// A line's left side: a bare symbol is stored by name (labels such as `⟨L⟩` are symbols
/// that the expression grammar would not read back), anything else as an expression.
fn lhs_json(e: &Expr) -> Json {
    match e.as_sym() {
        Some(s) => json!({ "symbol": s.name(), "primes": s.primes(), "positive": s.is_positive() }),
        None => json!(plain(e)),
    }
}

fn decode(bytes: &[u8], key: &str, decls: &Declarations) -> Option<Value> {
    let doc: Json = serde_json::from_slice(bytes).ok()?;
    if doc.get("format")?.as_u64()? != u64::from(CACHE_FORMAT) || doc.get("key")?.as_str()? != key {
        return None;
    }
    let v = doc.get("value")?;
    if doc.get("checksum")?.as_str()? != checksum(key, v) {
        return None;
    }
    let expr = |j: &Json| -> Option<Expr> {
        let text = j.as_str()?;
        let e = parse_with(text, decls).ok()?;
        // The printer promises print → parse is the identity; check it rather than trust it.
        (plain(&e) == text).then_some(e)
    };
    if let Some(e) = v.get("expr") {
        return expr(e).map(Value::Expr);
    }
    if let Some(es) = v.get("exprs") {
        return es.as_array()?.iter().map(expr).collect::<Option<Vec<_>>>().map(Value::Exprs);
    }
    let lines = v.get("lines")?.as_array()?;
    let mut out = Vec::with_capacity(lines.len());
    for l in lines {
        let text = |k: &str| -> Option<Option<String>> {
            match l.get(k)? {
                Json::Null => Some(None),
                Json::String(s) => Some(Some(s.clone())),
                _ => None,
            }
        };
        if let Some(t) = l.get("text") {
            out.push(Line::Text(t.as_str()?.to_string()));
            continue;
        }
        let lhs = match l.get("lhs")? {
            Json::Object(o) => {
                let name = o.get("symbol")?.as_str()?;
                let primes = u8::try_from(o.get("primes")?.as_u64()?).ok()?;
                let s = if o.get("positive")?.as_bool()? { Symbol::positive(name) } else { Symbol::new(name) };
                Expr::sym(s.with_primes(primes))
            }
            j => expr(j)?,
        };
        out.push(Line::Equation { label: text("label")?, lhs, rhs: expr(l.get("rhs")?)?, note: text("note")? });
    }
    Some(Value::Lines(out))
}

/// Writes `dir/name` whole or not at all: a temporary file in the same directory, renamed.
fn write_atomically(dir: &Path, name: &str, bytes: &[u8]) -> std::io::Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    std::fs::create_dir_all(dir)?;
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp = dir.join(format!(".{name}.{}.{n}.tmp", std::process::id()));
    let result = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, dir.join(name)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}
