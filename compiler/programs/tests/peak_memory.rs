//! A long program's memory: the job on a generated G-code raster of 100,000 blocks (a tenth
//! of them arcs) holds at most 100 MB of heap at its peak, from reading the program to the
//! compensated bytes and the report, and at most 80 MB when the report's lines are handed
//! on rather than kept (as tablec runs it). A counting global allocator watches it.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use adwi_programs::{CompensateJob, CompensateOptions};

/// Counts the bytes allocated and not yet freed, and their peak.
struct Peak;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(live, Ordering::Relaxed);
}

// SAFETY: delegates every call to the system allocator unchanged.
unsafe impl GlobalAlloc for Peak {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        // SAFETY: as above.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // The old and the new block both live while the bytes are copied.
        grew(new_size);
        // SAFETY: as above.
        let new = unsafe { System.realloc(ptr, layout, new_size) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        new
    }
}

#[global_allocator]
static ALLOCATOR: Peak = Peak;

/// A raster pocket of `lines` blocks as a CAM post writes it (as `tests/programs_gcode.rs`
/// generates it): G1 passes joined by half-circle arcs, every block with X Y Z A B C.
fn raster_program(lines: usize) -> String {
    let mut out = String::from("%\nO2000 (RASTER POCKET)\nN1 G21 G90 G17 G54\n");
    out += "N2 G0 X-200.000 Y-200.000 Z20.000 A0. B90. C0.\nN3 S9000 M3\n";
    let mut n = 4;
    let (mut x, mut y) = (-200.0f64, -200.0f64);
    let mut forward = true;
    let mut step = 2.0;
    out += "N4 G1 X-200.000 Y-200.000 Z-1.000 A0. B90. C0. F600.\n";
    while n < lines {
        n += 1;
        if n % 10 == 0 {
            if !(-200.0..=200.0).contains(&(y + step)) {
                step = -step;
            }
            y += step;
            let cw = if forward { "G3" } else { "G2" };
            out += &format!(
                "N{n} {cw} X{x:.3} Y{y:.3} Z-1.000 I0. J{:.3} A0. B90. C0.\n",
                step / 2.0
            );
            forward = !forward;
        } else {
            x += if forward { 4.5 } else { -4.5 };
            out += &format!("N{n} G1 X{x:.3} Y{y:.3} Z-1.000 A0. B90. C0.\n");
        }
    }
    out += &format!("N{} M30\n%\n", n + 1);
    out
}

/// A table around the raster (its work offset at 1750, 450, 1200): errors of 1-2 mm.
fn table_bytes() -> Vec<u8> {
    use adwi_compile::build::{compile, BuildOptions};
    use adwi_samples::{parse_samples, ColumnMap};
    let mut csv = String::from("x,y,z,dx,dy,dz,rx,ry,rz\n");
    for i in 0..7 {
        for j in 0..7 {
            for k in 0..7 {
                let p = [
                    1350.0 + 150.0 * i as f64,
                    50.0 + 150.0 * j as f64,
                    800.0 + 150.0 * k as f64,
                ];
                let e = [1.0 + 1e-4 * p[1], -0.5 + 2e-4 * p[0], 0.8 - 1e-4 * p[2]];
                csv += &format!(
                    "{},{},{},{},{},{},1e-4,-2e-4,5e-5\n",
                    p[0], p[1], p[2], e[0], e[1], e[2]
                );
            }
        }
    }
    let samples = parse_samples("t.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    compile(&samples, &BuildOptions::default(), &|_| {})
        .unwrap()
        .0
}

/// The heap's peak, bytes, while `work` runs.
fn peak_of<T>(work: impl FnOnce() -> T) -> (T, usize) {
    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let done = work();
    (done, PEAK.load(Ordering::Relaxed) - before)
}

// One test: the allocator counts every thread's bytes, so the runs are measured one after
// the other.
#[test]
fn a_100000_block_g_code_program_peaks_below_100_mb_of_heap_and_below_80_mb_written_as_it_goes() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("t.tbl");
    std::fs::write(&table, table_bytes()).unwrap();
    let program = dir.path().join("raster.nc");
    std::fs::write(&program, raster_program(100_000)).unwrap();
    let options = |output: &str| {
        let mut options = CompensateOptions::new(&table, &program);
        options.gcode.work_offsets = vec![(54, [1750.0, 450.0, 1200.0, 0.0, 0.0, 0.0])];
        options.limits.beyond_evidence = true;
        options.output = Some(dir.path().join(output));
        options
    };
    // Every line kept (the Python package's run).
    let (done, kept_peak) = peak_of(|| {
        let job = CompensateJob::new(options("kept.nc")).unwrap();
        job.run().unwrap()
    });
    let summary = done.report.summary();
    // Every block corrected: the numbers of every target rewritten.
    assert_eq!(summary.total, 99_998, "{summary}");
    assert_eq!(summary.corrected, summary.total, "{summary}");
    assert!(done.output.len() > 5_000_000);
    drop(done);
    // The lines handed on and dropped, the program written (tablec's run).
    let (written, written_peak) = peak_of(|| {
        let job = CompensateJob::new(options("written.nc")).unwrap();
        job.run_and_write(drop).unwrap()
    });
    assert_eq!(written.summary, summary);
    eprintln!(
        "raster of 100,000 blocks: heap peak {:.1} MB with every line kept, {:.1} MB written \
         as it goes",
        kept_peak as f64 / 1e6,
        written_peak as f64 / 1e6
    );
    assert!(kept_peak <= 100_000_000, "{kept_peak} bytes");
    assert!(written_peak <= 80_000_000, "{written_peak} bytes");
}
