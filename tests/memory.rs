//! Inputs designed to cost out of proportion to their size: 10⁵ distinct
//! groups (indexed, not scanned).

use lse_deform::constraints::{Constraint, ConstraintSet};

// ---------------------------------------------------------------------------
// Groups

/// 3·10⁵ distinct groups: added and each looked up once. Indexed by name
/// this takes well under a second; the former scan of the group list per
/// constraint and per lookup was 4.5·10¹⁰ comparisons each way (10⁵ groups
/// took 22 s in `deform`), minutes here.
#[test]
fn distinct_groups_are_indexed_not_scanned() {
    const N: usize = 300_000;
    let set = ConstraintSet::from_vec(
        (0..N)
            .map(|i| Constraint::position(i, [0.0; 3]).in_group(format!("g{i}")))
            .collect(),
    )
    .unwrap();
    assert_eq!(set.group_names().len(), N);
    for i in (0..N).rev() {
        assert_eq!(set.group(&format!("g{i}")), &[i]);
    }
    assert!(set.group("g").is_empty());
}
