//! Batch lanes: the host's SIMD width and the refill schedule of a batch.

use lagrangian::compile::simd_lanes;
use lagrangian::integrate::LaneRefill;

#[test]
fn simd_lanes_matches_the_host_features() {
    let lanes = simd_lanes();
    #[cfg(target_arch = "x86_64")]
    {
        let want = if std::arch::is_x86_feature_detected!("avx512f") {
            8
        } else if std::arch::is_x86_feature_detected!("avx2") {
            4
        } else {
            2
        };
        assert_eq!(lanes, want);
    }
    assert!([1, 2, 4, 8].contains(&lanes), "lanes = {lanes}");
}

/// Seven trajectories over three lanes, ending in an order chosen by hand: every trajectory
/// is loaded exactly once, a finished lane gets the next unstarted one, and lanes empty only
/// when nothing remains.
#[test]
fn refill_loads_each_trajectory_once_into_the_lane_that_ended() {
    let mut r = LaneRefill::new(3, 7);
    assert_eq!((r.lane(0), r.lane(1), r.lane(2)), (Some(0), Some(1), Some(2)));
    assert_eq!(r.finish(1), Some(3));
    assert_eq!(r.lane(1), Some(3));
    assert_eq!((r.lane(0), r.lane(2)), (Some(0), Some(2)), "other lanes untouched");
    assert_eq!(r.finish(1), Some(4));
    assert_eq!(r.finish(0), Some(5));
    assert_eq!(r.finish(2), Some(6));
    assert!(!r.done());
    assert_eq!(r.finish(2), None);
    assert_eq!(r.lane(2), None);
    assert_eq!(r.finish(0), None);
    assert!(!r.done(), "lane 1 still holds trajectory 4");
    assert_eq!(r.finish(1), None);
    assert!(r.done());
}

#[test]
fn refill_with_fewer_trajectories_than_lanes_leaves_the_rest_empty() {
    let r = LaneRefill::new(4, 2);
    assert_eq!((r.lane(0), r.lane(1), r.lane(2), r.lane(3)), (Some(0), Some(1), None, None));
    assert!(LaneRefill::new(4, 0).done());
}
