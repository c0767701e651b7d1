//! Tests of `src/plot.rs` (formerly its in-crate unit tests).
use lagrangian::plot::*;

use plotters::prelude::DrawingAreaErrorKind;
use plotters_backend::DrawingErrorKind;
use plotters_bitmap::BitMapBackendError;
/// A full disk while a PNG or GIF is written reads as the operating system says it (was
/// Rust's `Debug`: `ImageError(IoError(Custom { kind: Other, … }))`).
#[test]
fn bitmap_write_errors_read_as_the_os_says() {
    let disk_full = || std::io::Error::from_raw_os_error(28);
    let e =
        DrawingAreaErrorKind::BackendError(DrawingErrorKind::DrawingError(BitMapBackendError::IOError(disk_full())));
    assert_eq!(describe_bitmap_error(&e), disk_full().to_string());
    assert!(!describe_bitmap_error(&e).contains("Os {"));
}

#[test]
fn pendulum_fixed_points() {
    // H = p²/2 + (1 − cos q): O at 0 (level 0), X at ±π (level 2), by hand.
    let f = |q: f64, p: f64| 0.5 * p * p + 1.0 - q.cos();
    let fps = fixed_points(&f, -1.25 * std::f64::consts::PI, 1.25 * std::f64::consts::PI);
    let o: Vec<_> = fps.iter().filter(|p| p.elliptic).collect();
    let x: Vec<_> = fps.iter().filter(|p| !p.elliptic).collect();
    assert_eq!(o.len(), 1);
    assert!(o[0].q.abs() < 1e-9);
    assert_eq!(x.len(), 2);
    for p in x {
        assert!((p.q.abs() - std::f64::consts::PI).abs() < 1e-9, "{p:?}");
        assert!((p.level - 2.0).abs() < 1e-12);
    }
}

#[test]
fn an_orbit_retraced_a_hundred_times_is_drawn_about_once() {
    let lap: Vec<(f64, f64)> = (0..2000).map(|i| (i as f64 * 0.00314159).sin_cos()).collect();
    let laps: Vec<(f64, f64)> = (0..100).flat_map(|_| lap.iter().copied()).collect();
    let cell = (2.0 / 960.0, 2.0 / 680.0);
    let once: usize = decimate(&lap, cell).iter().map(Vec::len).sum();
    let all: usize = decimate(&laps, cell).iter().map(Vec::len).sum();
    assert!(once < 2000 && all < once + once / 5, "one lap {once} points, a hundred {all}");
    // Every point kept is a point of the orbit, and the kept path has no gap wider than
    // a few cells.
    for piece in decimate(&laps, cell) {
        for w in piece.windows(2) {
            assert!((w[0].0 - w[1].0).hypot(w[0].1 - w[1].1) < 0.02, "{w:?}");
        }
    }
}

#[test]
fn angles_wrap_into_the_half_open_interval() {
    use std::f64::consts::PI;
    assert_eq!(wrap_angle(PI), PI);
    assert_eq!(wrap_angle(-PI), PI);
    assert!((wrap_angle(3.0 * PI + 0.5) - (-PI + 0.5)).abs() < 1e-12);
    assert!(is_angle(&|q: f64, p: f64| 0.5 * p * p - q.cos()));
    assert!(!is_angle(&|q: f64, p: f64| 0.5 * p * p + q * q));
    // A rotation crossing the seam is cut there, not joined across the frame.
    let pieces = split_at_seam(&[(3.0, 1.0), (3.2, 1.0), (3.4, 1.0)]);
    assert_eq!(pieces.len(), 2);
}

#[test]
fn contour_segments_join_into_polylines() {
    let xs: Vec<f64> = (0..=40).map(|i| -2.0 + 0.1 * i as f64).collect();
    let vals: Vec<Vec<f64>> = xs.iter().map(|&y| xs.iter().map(|&x| x * x + y * y).collect()).collect();
    let segs = contour_segments(&vals, &xs, &xs, 1.0);
    let n = segs.len();
    let lines = chain_segments(segs);
    assert_eq!(lines.len(), 1, "the unit circle is one closed polyline");
    assert_eq!(lines[0].len(), n + 1);
    assert_eq!(lines[0].first(), lines[0].last());
}

#[test]
fn contour_of_a_circle() {
    // f = x² + y² at level 1: every segment end lies near the unit circle.
    let xs: Vec<f64> = (0..=40).map(|i| -2.0 + 0.1 * i as f64).collect();
    let vals: Vec<Vec<f64>> = xs.iter().map(|&y| xs.iter().map(|&x| x * x + y * y).collect()).collect();
    let segs = contour_segments(&vals, &xs, &xs, 1.0);
    assert!(segs.len() > 40);
    for (a, b) in segs {
        for (x, y) in [a, b] {
            assert!(((x * x + y * y).sqrt() - 1.0).abs() < 0.01);
        }
    }
}
