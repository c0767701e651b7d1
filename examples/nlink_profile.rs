//! Profiling aid: derives the n-link pendulum's W and F repeatedly.
//! Run: `cargo run --release --example nlink_profile -- N REPS`
use lagrangian::mechanics::System;
use lagrangian::Declarations;

#[path = "../tests/it/support/n_link.rs"]
mod n_link;
use n_link::n_link;

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("number")).collect();
    let (n, reps) = (args.first().copied().unwrap_or(10), args.get(1).copied().unwrap_or(20));
    let (l, coords, positive) = n_link(n);
    let coords: Vec<&str> = coords.iter().map(String::as_str).collect();
    let d = Declarations::new().with_positive(positive.iter().map(String::as_str));
    let s = System::from_lagrangian_with(&l, &coords, &d).expect("valid");
    let t0 = std::time::Instant::now();
    let mut ops = 0;
    for _ in 0..reps {
        let (w, f) = s.mass_matrix_split().expect("W, F");
        ops = w.iter().enumerate().map(|(i, r)| r[i..].iter().map(|e| e.op_count()).sum::<usize>()).sum::<usize>()
            + f.iter().map(|e| e.op_count()).sum::<usize>();
    }
    eprintln!("n = {n}: {:.3} ms per derivation, {ops} ops", t0.elapsed().as_secs_f64() * 1e3 / reps as f64);
    if std::env::var_os("PRINT").is_some() {
        let (w, f) = s.mass_matrix_split().expect("W, F");
        for (i, row) in w.iter().enumerate() {
            for (j, x) in row.iter().enumerate().skip(i) {
                println!("W[{}][{}] = {x}", i + 1, j + 1);
            }
        }
        for (i, x) in f.iter().enumerate() {
            println!("F[{}] = {x}", i + 1);
        }
    }
}
