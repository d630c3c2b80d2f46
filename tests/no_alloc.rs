//! Queries and compensations never allocate: a counting global allocator watches 100,000
//! of each, through every way of holding a table (owned bytes, memory map, a swappable
//! handle, the C ABI).

use crate::common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use adwi_runtime::capi::{self, AdwiCompensation, AdwiCorrection, AdwiResult};
use adwi_runtime::{Status, Table, TableSwap, Target};

/// Counts allocations made by a thread while its `COUNTING` flag is set.
struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    /// Per thread, so that tests running in parallel do not count each other's
    /// allocations.
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn note() {
    // `try_with`: the flag may already be gone while a thread shuts down.
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
    }
}

// SAFETY: delegates every call to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: as above.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        note();
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations (and frees) made by `f` on this thread.
fn allocations_in(f: impl FnOnce()) -> u64 {
    let before = ALLOCATIONS.with(Cell::get);
    COUNTING.with(|c| c.set(true));
    f();
    COUNTING.with(|c| c.set(false));
    ALLOCATIONS.with(Cell::get) - before
}

const QUERIES: usize = 100_000;

#[test]
fn queries_and_compensations_allocate_nothing() {
    let bytes = common::lattice_table(7, 1.0);
    let owned = Table::from_vec(&bytes).unwrap();
    let dir = std::env::temp_dir().join(format!("adwi-no-alloc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("lattice.tbl");
    std::fs::write(&path, &bytes).unwrap();
    // SAFETY: the file is private to this test and not modified while mapped.
    let mapped = unsafe { Table::open(&path) }.unwrap();
    let live = TableSwap::new(Table::from_vec(&bytes).unwrap());
    let mut handle = std::ptr::null_mut();
    let path_c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: a valid C string and out-pointer.
    let code = unsafe { capi::adwi_table_open(path_c.as_ptr(), &mut handle) };
    assert_eq!(code, AdwiResult::Ok);

    // Targets in the grid, some outside it, one not finite: every path of a query.
    let mut targets = common::targets(11, QUERIES);
    targets[0] = [0.0; 3];
    targets[1] = [f64::NAN, 0.0, 0.0];
    targets[2] = common::ORIGIN_MM;
    // The swappable handle registers this thread on its first load (once per thread).
    live.query(targets[3]);

    let mut ok = 0usize;
    let mut converged = 0usize;
    let mut checksum = 0.0;
    let count = allocations_in(|| {
        for (i, p) in targets.iter().enumerate() {
            let target = Target {
                position_mm: *p,
                config: if i % 2 == 0 { None } else { Some(1) },
                rotation_rad: None,
                tcp_mm: None,
            };
            let a = owned.query_target(&target);
            let b = mapped.query(*p);
            let c = live.query_target(&target);
            let k = owned.compensate(&target, 1e-9, 20);
            let l = live.compensate(&target, 1e-9, 20);
            let e = mapped
                .explain(&target)
                .map(|p| p.neighbours.len())
                .unwrap_or(0);
            let mut from_c = AdwiCorrection::default();
            let mut comp_c = AdwiCompensation::default();
            // SAFETY: a live handle, three readable doubles, writable outputs.
            let codes = unsafe {
                (
                    capi::adwi_table_query(handle, p.as_ptr(), -1, &mut from_c),
                    capi::adwi_table_compensate(handle, p.as_ptr(), -1, 1e-9, 20, &mut comp_c),
                )
            };
            // A target that is not finite has no command: the C compensation refuses it.
            let compensated = if p.iter().all(|v| v.is_finite()) {
                AdwiResult::Ok
            } else {
                AdwiResult::InvalidArgument
            };
            assert_eq!(codes, (AdwiResult::Ok, compensated));
            ok += usize::from(a.status == Status::Ok);
            converged += usize::from(k.converged);
            let terms = [
                a.position_error_mm[0],
                b.position_error_mm[1],
                c.position_error_mm[2],
                k.command_position_mm[0],
                l.residual_mm,
                e as f64,
                from_c.position_error_mm[0],
                comp_c.command_position_mm[1],
            ];
            // Non-finite terms come from the NaN and outside targets.
            checksum += terms.iter().filter(|t| t.is_finite()).sum::<f64>();
        }
    });
    // SAFETY: the handle from `adwi_table_open`, closed once.
    unsafe { capi::adwi_table_close(handle) };
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(
        count, 0,
        "{count} allocations in {QUERIES} rounds of queries"
    );
    // The loop did real work: most targets answered, most compensations converged.
    assert!(ok > QUERIES * 9 / 10, "only {ok} answers");
    assert!(converged > QUERIES * 9 / 10, "only {converged} converged");
    assert!(checksum.is_finite() && checksum != 0.0);
}

#[test]
fn the_counter_sees_allocations() {
    // Guards the test above against a counter that counts nothing.
    let count = allocations_in(|| {
        std::hint::black_box(vec![1u8; 64]);
    });
    assert_eq!(count, 2, "one allocation and one free");
}

/// Hybrid queries (two forward kinematics, a logarithm, the joint screen) allocate nothing
/// either, through the Rust API and the C ABI.
#[test]
fn hybrid_queries_allocate_nothing() {
    use adwi_compile::build::BuildOptions;

    let (_, samples, calibration) = common::kr150_calibration();
    let options = BuildOptions {
        cell_mm: Some(50.0),
        joint_radius_deg: Some(15.0),
        ..BuildOptions::default()
    };
    let bytes = common::hybrid_table_bytes(&samples, &calibration.prepared_model(), &options);
    let table = Table::from_vec(&bytes).unwrap();
    assert!(table.is_hybrid());
    // SAFETY: valid bytes and out-pointer; the handle copies the bytes.
    let mut handle = std::ptr::null_mut();
    let code = unsafe { capi::adwi_table_open_bytes(bytes.as_ptr(), bytes.len(), &mut handle) };
    assert_eq!(code, AdwiResult::Ok);

    let queries = wiggled_poses(&samples, 1.0, 20.0);
    let mut ok = 0usize;
    let mut checksum = 0.0;
    let count = allocations_in(|| {
        for (p, q) in &queries {
            let a = table.query_with_joints(&Target::at(*p), q);
            let missing = table.query_target(&Target::at(*p));
            let mut from_c = AdwiCorrection::default();
            // SAFETY: a live handle, readable target and joints, a writable output.
            let code = unsafe {
                capi::adwi_table_query_joints(
                    handle,
                    p.as_ptr(),
                    -1,
                    q.as_ptr(),
                    q.len(),
                    &mut from_c,
                )
            };
            assert_eq!(code, AdwiResult::Ok);
            assert_eq!(missing.status, Status::MissingJoints);
            ok += usize::from(a.status == Status::Ok);
            checksum += a.orientation_error_rad[0] + from_c.position_error_mm[1];
        }
    });
    // SAFETY: the handle from `adwi_table_open_bytes`, closed once.
    unsafe { capi::adwi_table_close(handle) };
    assert_eq!(count, 0, "hybrid queries allocated {count} times");
    assert!(ok > queries.len() / 2, "only {ok} answered");
    assert!(checksum.is_finite());
}

/// The served field that turns with the tool (four vectors a node, the nominal approach
/// axis from the model part's forward kinematics) allocates nothing either.
#[test]
fn tool_axis_served_queries_allocate_nothing() {
    use adwi_compile::build::{BuildOptions, ServedField};

    let (_, all, calibration) = common::kr150_calibration();
    let picked: Vec<usize> = (0..all.len()).step_by(3).collect();
    let samples = all.subset(&picked);
    let options = BuildOptions {
        cell_mm: Some(100.0),
        served_field: ServedField::KrigingToolAxis,
        ..BuildOptions::default()
    };
    let bytes = common::hybrid_table_bytes(&samples, &calibration.prepared_model(), &options);
    let table = Table::from_vec(&bytes).unwrap();
    assert_eq!(table.header().served_field, ServedField::KrigingToolAxis);
    // Joints within the table's tolerance of the positions (a few degrees on a 1.5 m arm).
    let queries = wiggled_poses(&samples, 1.0, 40.0);
    let mut ok = 0usize;
    let mut checksum = 0.0;
    let count = allocations_in(|| {
        for (p, q) in &queries {
            let a = table.query_with_joints(&Target::at(*p), q);
            ok += usize::from(a.status == Status::Ok);
            checksum += a.position_error_mm[2] + a.orientation_error_rad[0];
        }
    });
    assert_eq!(count, 0, "tool-axis queries allocated {count} times");
    assert!(ok > queries.len() / 2, "only {ok} answered");
    assert!(checksum.is_finite());
}

/// 20 000 queries near the samples' poses: each joint moved by up to `joint_deg`, the
/// target by up to `position_mm` along every axis, deterministically.
fn wiggled_poses(
    samples: &adwi_samples::SampleSet,
    joint_deg: f64,
    position_mm: f64,
) -> Vec<([f64; 3], [f64; 6])> {
    let joints = samples.joints.as_ref().unwrap();
    (0..20_000)
        .map(|i| {
            let s = i % samples.len();
            let wiggle = (i as f64 * 0.37).sin();
            let q: [f64; 6] =
                std::array::from_fn(|a| joints.row(s)[a] + (joint_deg * wiggle).to_radians());
            let p = samples.nominal_mm[s].map(|v| v + position_mm * wiggle);
            (p, q)
        })
        .collect()
}

/// A hybrid table's posture term (a cell's list of samples weighed in pose space) adds
/// no allocation to a served query.
#[test]
fn posture_term_queries_allocate_nothing() {
    use adwi_compile::build::BuildOptions;
    use adwi_compile::posture::Posture;
    use adwi_runtime::posture::PostureParams;

    let (_, samples, calibration) = common::kr150_calibration();
    let options = BuildOptions {
        cell_mm: Some(100.0),
        posture: Posture::Given(PostureParams {
            radius_mm: 300.0,
            length_rad: 0.6,
            floor: 0.3,
        }),
        ..BuildOptions::default()
    };
    let bytes = common::hybrid_table_bytes(&samples, &calibration.prepared_model(), &options);
    let table = Table::from_vec(&bytes).unwrap();
    assert!(table.posture().is_some());
    let queries = wiggled_poses(&samples, 1.0, 20.0);
    let mut ok = 0usize;
    let mut checksum = 0.0;
    let count = allocations_in(|| {
        for (p, q) in &queries {
            let c = table.query_with_joints(&Target::at(*p), q);
            ok += usize::from(c.status == Status::Ok);
            checksum += c.position_error_mm[0];
        }
    });
    assert_eq!(count, 0, "posture-term queries allocated {count} times");
    assert!(ok > queries.len() / 2, "only {ok} answered");
    assert!(checksum.is_finite());
}
