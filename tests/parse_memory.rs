//! The memory of parsing a constraints file, counted by a global allocator
//! (this test binary holds one test, so nothing else allocates meanwhile):
//! the parser holds the constraints, not a JSON document tree. A
//! `serde_json::Value` tree of the format took 15–28 bytes per byte of text
//! (a 77 MiB body peaked at 2.1 GB); the constraints take about 3 (most
//! of it the moment their list doubles its capacity).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use lse_deform::constraints::{parse_constraints, read_constraints_file};

struct Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let now = CURRENT.fetch_add(bytes, Relaxed) + bytes;
    PEAK.fetch_max(now, Relaxed);
}

// SAFETY: every call is forwarded to the system allocator unchanged; only
// sizes are counted.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            // The old block may be copied into the new one: both are live
            // for a moment.
            grew(new_size);
            CURRENT.fetch_sub(layout.size(), Relaxed);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// `f`'s result and the most bytes it had allocated at once beyond what
/// was allocated before it.
fn peak_during<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = CURRENT.load(Relaxed);
    PEAK.store(base, Relaxed);
    let result = f();
    (result, PEAK.load(Relaxed) - base)
}

/// About 16 MB of constraints of every type, some soft, in 250 groups, as
/// `ConstraintSet::to_json` and other programs write them.
fn big_file() -> String {
    let mut text = String::from("{\"mesh\": null, \"constraints\": [\n");
    let n = 160_000;
    for i in 0..n {
        let x = i as f64 * 1e-3;
        let item = match i % 4 {
            0 => format!(
                r#"{{"type": "position", "vertex": {i}, "target": [{x}, 0.25, -1.5], "group": "g{}"}}"#,
                i % 1000
            ),
            1 => format!(
                r#"{{"type": "edge", "vertices": [{i}, {}], "t": 0.3, "target": [0, {x}, 1], "weight": 10}}"#,
                i + 1
            ),
            2 => format!(
                r#"{{"type": "face", "vertices": [{i}, {}, {}], "barycentric": [0.2, 0.3], "target": [{x}, 1, 0]}}"#,
                i + 1,
                i + 2
            ),
            _ => format!(
                r#"{{"type": "relative", "vertices": [{i}, {}], "vector": [0, 0, {x}], "comment": "a note"}}"#,
                i + 7
            ),
        };
        text.push_str(&item);
        text.push_str(if i + 1 < n { ",\n" } else { "\n" });
    }
    text.push_str("]}\n");
    text
}

#[test]
fn parsing_holds_the_constraints_not_a_document_tree() {
    let text = big_file();
    let (set, from_text) = peak_during(|| parse_constraints(&text).unwrap());
    assert_eq!(set.len(), 160_000);
    assert_eq!(set.group_names().len(), 250);
    let ratio = from_text as f64 / text.len() as f64;
    eprintln!(
        "parse_constraints: {} bytes of text, peak {from_text} bytes allocated ({ratio:.2} per byte)",
        text.len()
    );
    assert!(ratio < 4.0, "{ratio:.2} bytes per byte of text");

    // From a file: read as it is parsed, never held whole.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.json");
    std::fs::write(&path, &text).unwrap();
    drop(text);
    let (again, from_file) = peak_during(|| {
        read_constraints_file(&path, lse_deform::limits::MemoryBudget::default()).unwrap()
    });
    let size = std::fs::metadata(&path).unwrap().len() as f64;
    let ratio = from_file as f64 / size;
    eprintln!("read_constraints_file: peak {from_file} bytes ({ratio:.2} per byte of the file)");
    assert!(ratio < 4.0, "{ratio:.2} bytes per byte of the file");
    assert_eq!(again, set);
}
