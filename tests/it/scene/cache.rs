//! The on-disk derivation cache across `lagrangian run` processes: a second run of a scene
//! with other numbers loads its derivations (the plan says so), its outputs are byte for byte
//! those of a run without the cache, and a damaged cache is survived. Every run here uses a
//! temporary cache directory, never the user's.

use std::path::Path;
use std::process::Command;

/// The double pendulum with the first angle given (the symbolic content is the same for
/// every angle).
fn scene(theta1: &str) -> String {
    format!(
        "coordinates θ1, θ2\nparameters m1 = 1, m2 = 1, l1 = 1, l2 = 1, g = 9.81 positive\n\
         L = 1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2)\n\
         \x20   + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)\n\
         el\nH = legendre(L)\nprint H\n\
         simulate θ1 = {theta1}, θ2 = 2.5, θ1' = 0, θ2' = 0 for t in 0..2 with dop853 tol = 1e-10 as a\n\
         plot energy from a to energy.svg\nexport t, θ1, θ2, H from a to run.csv\n"
    )
}

struct Out {
    stdout: String,
    files: Vec<(String, Vec<u8>)>,
}

/// Runs `text` in a fresh output directory with extra arguments; the cache directory, if
/// any, is given by the caller.
fn run(text: &str, args: &[&str]) -> Out {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dp.scene");
    std::fs::write(&path, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_lagrangian"))
        .arg("run")
        .arg(&path)
        .args(args)
        .env_remove("LAGRANGIAN_CACHE_DIR")
        .env("XDG_CACHE_HOME", dir.path().join("no-such-cache"))
        .current_dir(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(!dir.path().join("no-such-cache").exists(), "the default cache directory was used");
    let mut files = Vec::new();
    for name in ["energy.svg", "run.csv"] {
        files.push((name.to_string(), std::fs::read(dir.path().join(name)).unwrap()));
    }
    Out { stdout, files }
}

fn explained<'a>(stdout: &'a str, step: &str) -> Vec<&'a str> {
    stdout.lines().filter(|l| l.contains(step)).collect()
}

fn cache_args(dir: &Path) -> Vec<String> {
    vec!["--cache-dir".into(), dir.display().to_string()]
}

#[test]
fn a_second_process_loads_the_derivations_and_writes_the_same_bytes() {
    let cache = tempfile::tempdir().unwrap();
    let args = cache_args(cache.path());
    let with = |extra: &[&str], text: &str| {
        let mut a: Vec<&str> = args.iter().map(String::as_str).collect();
        a.extend_from_slice(extra);
        run(text, &a)
    };
    let first = with(&["--explain"], &scene("2.0"));
    for step in ["Euler–Lagrange", "Legendre transform", "energy function"] {
        let lines = explained(&first.stdout, step);
        assert!(lines.iter().all(|l| l.contains("built")), "{step}: {lines:?}");
    }
    assert!(std::fs::read_dir(cache.path()).unwrap().count() >= 3, "nothing was written to the cache");

    let second = with(&["--explain"], &scene("1.5"));
    for step in ["Euler–Lagrange", "Legendre transform", "energy function"] {
        let lines = explained(&second.stdout, step);
        assert!(
            !lines.is_empty() && lines.iter().all(|l| l.contains("loaded") && l.contains("disk cache")),
            "{step}: {lines:?}"
        );
    }
    assert!(second.stdout.contains("loaded from the disk cache"), "{}", second.stdout);

    // The same scene without the cache: identical printed results and files.
    let plain = run(&scene("1.5"), &["--no-cache"]);
    let printed = |o: &Out| o.stdout.split("plan:").next().unwrap().to_string();
    assert_eq!(printed(&second), plain.stdout);
    assert_eq!(second.files, plain.files);
    assert_ne!(first.files, second.files, "the new initial angle was used");

    // `LAGRANGIAN_CACHE_DIR` chooses the directory too.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dp.scene");
    std::fs::write(&path, scene("1.0")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_lagrangian"))
        .args(["run", "--explain"])
        .arg(&path)
        .env("LAGRANGIAN_CACHE_DIR", cache.path())
        .current_dir(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("loaded from the disk cache"), "{stdout}");
}

#[test]
fn a_damaged_cache_is_rebuilt_not_an_error() {
    let cache = tempfile::tempdir().unwrap();
    let args = cache_args(cache.path());
    let a: Vec<&str> = args.iter().map(String::as_str).chain(["--explain"]).collect();
    let clean = run(&scene("2.0"), &a);
    let mut entries: Vec<_> = std::fs::read_dir(cache.path()).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    assert!(entries.len() >= 3);
    // Garbage, a truncated entry, and an entry of a future format.
    std::fs::write(&entries[0], b"\xff\xfe not json").unwrap();
    let text = std::fs::read_to_string(&entries[1]).unwrap();
    std::fs::write(&entries[1], &text[..text.len() / 2]).unwrap();
    let text = std::fs::read_to_string(&entries[2]).unwrap();
    std::fs::write(&entries[2], text.replace("\"format\":1", "\"format\":2")).unwrap();
    let damaged = run(&scene("2.0"), &a);
    assert!(damaged.stdout.contains("built"), "{}", damaged.stdout);
    assert_eq!(damaged.files, clean.files);
    // The damaged entries were rewritten: a third run loads everything.
    let third = run(&scene("2.0"), &a);
    for step in ["Euler–Lagrange", "Legendre transform", "energy function"] {
        assert!(explained(&third.stdout, step).iter().all(|l| l.contains("loaded")), "{}", third.stdout);
    }
}
