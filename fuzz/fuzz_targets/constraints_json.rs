//! Any text given to the constraint-file parser gives a constraint set or a
//! typed error; a set that comes back has finite coefficients and targets,
//! positive finite weights, and is checked against a small mesh without
//! panicking.
#![no_main]

use libfuzzer_sys::fuzz_target;
use lse_deform::constraints::parse_constraints;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(set) = parse_constraints(text) {
        for c in set.as_slice() {
            let row = c.kind.row();
            assert!(row.entries().iter().all(|&(_, v)| v.is_finite()));
            assert!(c.kind.rhs().iter().all(|v| v.is_finite()));
            assert!(c.weight.is_none_or(|w| w.is_finite() && w > 0.0));
        }
        let _ = set.check_vertices(100);
    }
});
