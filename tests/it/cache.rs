//! Tests of `src/cache.rs` (formerly its in-crate unit tests).
use lagrangian::cache::*;

use lagrangian::parse::{parse_with, Declarations};
use lagrangian::report::Line;
use lagrangian::{Expr, Symbol};
fn key(inputs: Vec<Expr>) -> CacheKey {
    CacheKey::symbolic(Step::Legendre, &[Symbol::new("x")], inputs)
}

#[test]
fn memory_holds_at_most_its_bound_and_drops_the_oldest() {
    let mut c = Cache::new();
    let nth = |i: usize| key(vec![Expr::int(i as i64)]);
    for i in 0..MAX_IN_MEMORY + 10 {
        c.insert(nth(i), Value::Expr(Expr::int(i as i64)));
    }
    // Inserting a key already held neither grows the map nor evicts.
    c.insert(nth(MAX_IN_MEMORY + 9), Value::Expr(Expr::zero()));
    assert_eq!(c.len(), MAX_IN_MEMORY);
    assert!(c.get(&nth(9)).is_none(), "the oldest ten are dropped");
    assert!(matches!(c.get(&nth(10)), Some(Value::Expr(e)) if e == Expr::int(10)));
    assert!(matches!(c.get(&nth(MAX_IN_MEMORY + 9)), Some(Value::Expr(e)) if e.is_zero()));
}

#[test]
fn a_stored_result_loads_identically_and_a_damaged_one_is_a_miss() {
    let dir = tempfile::tempdir().unwrap();
    let decls = Declarations::new().with_positive(["m"]);
    let l = parse_with("1/2 m x'^2 - x^4/4", &decls).unwrap();
    let h = parse_with("p_x^2/(2 m) + x^4/4", &decls).unwrap();
    let lines = vec![
        Line::labelled("E_x", Expr::var("⟨L⟩"), h.clone()),
        Line::text("note: a line of text"),
        Line::named("h", h.clone()).with_note("a note"),
    ];
    let mut c = Cache::with_dir(dir.path());
    c.insert(key(vec![l.clone()]), Value::Expr(h.clone()));
    c.insert(key(vec![h.clone()]), Value::Lines(lines.clone()));
    let mut fresh = Cache::with_dir(dir.path());
    assert!(matches!(fresh.load(&key(vec![l.clone()]), &decls), Some(Value::Expr(e)) if e == h));
    assert!(matches!(fresh.load(&key(vec![h.clone()]), &decls), Some(Value::Lines(v)) if v == lines));
    // Truncate every entry: each is now a miss, not an error.
    for f in std::fs::read_dir(dir.path()).unwrap() {
        let p = f.unwrap().path();
        let b = std::fs::read(&p).unwrap();
        std::fs::write(&p, &b[..b.len() / 2]).unwrap();
    }
    assert!(Cache::with_dir(dir.path()).load(&key(vec![l]), &decls).is_none());
}

#[test]
fn an_edited_value_with_a_matching_key_is_a_miss_and_non_files_are_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let decls = Declarations::new();
    let l = parse_with("x'^2/2 - x^2/2", &decls).unwrap();
    let h = parse_with("p_x^2/2 + x^2/2", &decls).unwrap();
    Cache::with_dir(dir.path()).insert(key(vec![l.clone()]), Value::Expr(h.clone()));
    let entry = std::fs::read_dir(dir.path()).unwrap().next().unwrap().unwrap().path();
    let text = std::fs::read_to_string(&entry).unwrap();
    // Well-formed, same key, an expression that re-parses: only the checksum tells.
    let edited = text.replace("p_x^2/2 + x^2/2", "p_x^2/2 + x^2");
    assert_ne!(edited, text);
    std::fs::write(&entry, edited).unwrap();
    assert!(Cache::with_dir(dir.path()).load(&key(vec![l.clone()]), &decls).is_none());
    std::fs::write(&entry, &text).unwrap();
    assert!(matches!(Cache::with_dir(dir.path()).load(&key(vec![l.clone()]), &decls), Some(Value::Expr(e)) if e == h));
    // The same entry reached through a symbolic link (to itself, or to /dev/zero) is ignored.
    #[cfg(unix)]
    {
        let real = dir.path().join("real.json");
        std::fs::rename(&entry, &real).unwrap();
        std::os::unix::fs::symlink(&real, &entry).unwrap();
        assert!(Cache::with_dir(dir.path()).load(&key(vec![l.clone()]), &decls).is_none());
        std::fs::remove_file(&entry).unwrap();
        std::os::unix::fs::symlink("/dev/zero", &entry).unwrap();
        assert!(Cache::with_dir(dir.path()).load(&key(vec![l]), &decls).is_none());
    }
}

#[test]
fn the_file_name_is_stable_and_assumptions_are_part_of_the_key() {
    // FNV-1a 128 of the empty string is its offset basis (the published constant).
    assert_eq!(file_name(""), "6c62272e07bb014262b821756295c58d.json");
    let m = Expr::sym(Symbol::new("m"));
    let m_pos = Expr::sym(Symbol::positive("m"));
    assert_ne!(disk_key(&key(vec![m.clone()]), None), disk_key(&key(vec![m_pos]), None));
    // The build is part of the key: another build never reads this one's entries.
    assert_ne!(disk_key(&key(vec![m.clone()]), Some("a")), disk_key(&key(vec![m]), Some("b")));
}
