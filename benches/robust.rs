//! Large inputs, measured (not timed tests). Prints one row per target with
//! the least thread CPU time of a few runs, and the growth exponents log(t(4N)/t(N))/log 4 of
//! simplifying and differentiating a sum of N unrelated symbols. SymEngine's rows come from
//! `benches/anchors/robust_symengine.sh`, which runs this bench and SymEngine back to back.
//!
//!     cargo bench --bench robust

use std::time::Duration;

use lagrangian::diff::diff;
use lagrangian::scene::{Mode, Options, Session};
use lagrangian::simplify::simplify;
use lagrangian::{parse, Symbol};

/// This thread's CPU time. The machine is shared (load 5–15 while these rows were taken), so
/// wall time mostly measures the queue; everything timed here runs on the calling thread.
fn thread_cpu() -> Duration {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; the clock id is a constant Linux knows.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

/// The least CPU time of `runs` calls of `f` on this thread, in seconds.
fn least(runs: usize, mut f: impl FnMut()) -> f64 {
    (0..runs)
        .map(|_| {
            let start = thread_cpu();
            f();
            thread_cpu() - start
        })
        .min()
        .unwrap_or(Duration::ZERO)
        .as_secs_f64()
}

fn sum_of_symbols(n: usize) -> String {
    (0..n).map(|i| format!("x{i}")).collect::<Vec<_>>().join(" + ")
}

/// `Σ c_k x^k`, k = 0..=400, coefficients 1..9 from a fixed sequence.
fn degree_400() -> String {
    (0..=400).map(|k| format!("{} x^{k}", 1 + (k * 7 + 3) % 9)).collect::<Vec<_>>().join(" + ")
}

/// `(x + 1)^n − (its expansion written out)`, coefficients by Pascal's rule.
fn binomial_minus_expansion(n: usize) -> String {
    let mut row = vec![num_bigint::BigInt::from(1)];
    for _ in 0..n {
        let mut next = vec![num_bigint::BigInt::from(1)];
        next.extend(row.windows(2).map(|w| &w[0] + &w[1]));
        next.push(num_bigint::BigInt::from(1));
        row = next;
    }
    let terms: Vec<String> = row.iter().enumerate().map(|(k, c)| format!("{c} x^{k}")).collect();
    format!("(x + 1)^{n} - ({})", terms.join(" + "))
}

fn scene_of_definitions(n: usize) -> String {
    let mut s = String::from("parameters m = 1\n");
    for i in 0..n {
        s.push_str(&format!("a{i} = {i} m + 1\n"));
    }
    s.push_str(&format!("print a{}\n", n - 1));
    s
}

fn exponent(t_n: f64, t_4n: f64) -> f64 {
    (t_4n / t_n).ln() / 4f64.ln()
}

fn main() {
    // `cargo bench` passes `--bench`; any other argument filters nothing here.
    let x5 = Symbol::new("x5");

    let big = sum_of_symbols(100_000);
    let t = least(3, || {
        let e = parse(&big).unwrap();
        let d = diff(&e, &x5);
        assert!(d.is_one());
    });
    println!("robust/sum_1e5_parse_diff        {:>10.4} s   (target < 1 s)", t);

    let poly = degree_400();
    let t = least(3, || {
        let e = parse(&poly).unwrap();
        std::hint::black_box(simplify(&e));
    });
    println!("robust/degree_400_simplify       {:>10.4} s   (target < 0.5 s)", t);

    let binom = binomial_minus_expansion(400);
    let t = least(3, || {
        let e = parse(&binom).unwrap();
        assert!(simplify(&e).is_zero());
    });
    println!("robust/binomial_400_minus_exp    {:>10.4} s   (target < 1 s)", t);

    let scene = scene_of_definitions(100_000);
    let t = least(3, || {
        let mut s = Session::new(Options::new(Mode::Scene));
        s.run_scene("defs.scene", &scene).unwrap();
        std::hint::black_box(s.take_output());
    });
    println!("robust/scene_1e5_definitions     {:>10.4} s   (target < 5 s)", t);

    for n in [2_000, 8_000] {
        let (a, b) = (sum_of_symbols(n), sum_of_symbols(4 * n));
        let (ea, eb) = (parse(&a).unwrap(), parse(&b).unwrap());
        let ta = least(5, || drop(std::hint::black_box(simplify(&ea))));
        let tb = least(5, || drop(std::hint::black_box(simplify(&eb))));
        println!(
            "robust/simplify_sum_{n}_vs_{}    {:>10.4} s {:>8.4} s   exponent {:.2} (target O(N log N): < 1.3)",
            4 * n,
            ta,
            tb,
            exponent(ta, tb)
        );
    }
    for n in [25_000, 100_000] {
        let (a, b) = (sum_of_symbols(n), sum_of_symbols(4 * n));
        let (ea, eb) = (parse(&a).unwrap(), parse(&b).unwrap());
        let ta = least(5, || drop(std::hint::black_box(diff(&ea, &x5))));
        let tb = least(5, || drop(std::hint::black_box(diff(&eb, &x5))));
        println!(
            "robust/diff_sum_{n}_vs_{}    {:>10.4} s {:>8.4} s   exponent {:.2} (target linear: ~1)",
            4 * n,
            ta,
            tb,
            exponent(ta, tb)
        );
    }
}
