//! A program and its report written by concurrent jobs: always a pair from one job, the
//! report naming the program it reports on by its hash.

use std::sync::{Arc, Barrier};

use adwi_programs::{CompensateJob, CompensateOptions};

/// A table correcting a constant 1 mm in x around the KR150-2 fixtures' targets.
fn table_bytes() -> Vec<u8> {
    use adwi_compile::build::{compile, BuildOptions};
    use adwi_samples::{parse_samples, ColumnMap};
    let mut csv = String::from("x,y,z,dx,dy,dz\n");
    for i in 0..6 {
        for j in 0..6 {
            for k in 0..6 {
                let p = [
                    1300.0 + 200.0 * i as f64,
                    -100.0 + 200.0 * j as f64,
                    700.0 + 200.0 * k as f64,
                ];
                csv += &format!("{},{},{},1,0,0\n", p[0], p[1], p[2]);
            }
        }
    }
    let samples = parse_samples("t.csv".as_ref(), csv.as_bytes(), &ColumnMap::default()).unwrap();
    compile(&samples, &BuildOptions::default(), &|_| {})
        .unwrap()
        .0
}

#[test]
fn concurrent_writers_leave_a_program_and_the_report_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("t.tbl"), table_bytes()).unwrap();
    std::fs::write(d.join("a.csv"), "x,y,z\n1500,200,1200\n1600,300,1100\n").unwrap();
    std::fs::write(d.join("b.csv"), "x,y,z\n1510,210,1200\n").unwrap();
    let job = |program: &str| {
        let mut o = CompensateOptions::new(d.join("t.tbl"), d.join(program));
        o.output = Some(d.join("o.csv"));
        o.report = Some(d.join("o.rep"));
        let job = CompensateJob::new(o).unwrap();
        let done = job.run().unwrap();
        (job, done)
    };
    let jobs = Arc::new([job("a.csv"), job("b.csv")]);
    for trial in 0..100 {
        let start = Arc::new(Barrier::new(2));
        let writers: Vec<_> = (0..2)
            .map(|k| {
                let (jobs, start) = (jobs.clone(), start.clone());
                std::thread::spawn(move || {
                    start.wait();
                    let (job, done) = &jobs[k];
                    job.write(done).unwrap();
                })
            })
            .collect();
        for w in writers {
            w.join().unwrap();
        }
        let program = std::fs::read(d.join("o.csv")).unwrap();
        let hash = format!("{:016x}", xxhash_rust::xxh3::xxh3_64(&program));
        let report = std::fs::read_to_string(d.join("o.rep")).unwrap();
        let rows: Vec<&str> = report.lines().skip(1).collect();
        assert!(!rows.is_empty());
        for row in rows {
            assert!(
                row.ends_with(&format!(",{hash}")),
                "trial {trial}: the program's hash is {hash}; the report's row: {row}"
            );
        }
    }
}

/// A job run twice: once keeping every line ([`CompensateJob::run`], then `write`), once
/// handing them on ([`CompensateJob::run_and_write`]): the same program, report, lines and
/// summary.
fn kept_and_handed_on(program_name: &str, program: &str) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("t.tbl"), table_bytes()).unwrap();
    std::fs::write(d.join(program_name), program).unwrap();
    let job = |out: &str| {
        let mut o = CompensateOptions::new(d.join("t.tbl"), d.join(program_name));
        o.output = Some(d.join(format!("{out}.out")));
        o.report = Some(d.join(format!("{out}.csv")));
        o.limits.max_correction_mm = 1.0005;
        CompensateJob::new(o).unwrap()
    };
    let kept = job("kept");
    let done = kept.run().unwrap();
    kept.write(&done).unwrap();
    let mut lines = Vec::new();
    let handed = job("handed").run_and_write(|l| lines.push(l)).unwrap();
    assert_eq!(lines, done.report.targets);
    assert_eq!(handed.summary, done.report.summary());
    assert_eq!(Some(handed.program_xxh3), done.report.program_xxh3);
    assert_eq!(handed.output, done.output);
    for ext in ["out", "csv"] {
        let read = |name: &str| std::fs::read(d.join(format!("{name}.{ext}"))).unwrap();
        assert_eq!(read("handed"), read("kept"), "{ext}");
    }
    let summary = handed.summary;
    assert!(
        summary.corrected > 0 && summary.corrected < summary.total,
        "{summary}"
    );
}

#[test]
fn lines_handed_on_give_the_program_report_and_summary_of_lines_kept() {
    let mut csv = String::from("x,y,z\n");
    for i in 0..40 {
        // Every fifth outside the table's grid: left unchanged, named in the report.
        let x = if i % 5 == 4 {
            9000.0
        } else {
            1400.0 + i as f64
        };
        csv += &format!("{x},{},1100\n", 100 + i);
    }
    kept_and_handed_on("p.csv", &csv);
}

#[test]
fn lines_handed_on_match_lines_kept_for_inline_and_declared_targets() {
    // Inline targets written before a declared one, one of them outside the table.
    let program = "MODULE M\n\
        PROC main()\n\
        MoveL [[1500,200,1200],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],v100,fine,tool0;\n\
        MoveL [[9000,200,1200],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],v100,fine,tool0;\n\
        MoveL p2,v100,fine,tool0;\n\
        ENDPROC\n\
        CONST robtarget p2:=[[1600,300,1100],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n\
        ENDMODULE\n";
    kept_and_handed_on("m.mod", program);
}
