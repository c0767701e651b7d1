//! Batch lanes: the host's SIMD width.

use lagrangian::compile::simd_lanes;

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
