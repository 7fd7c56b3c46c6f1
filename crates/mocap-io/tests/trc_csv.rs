//! TRC and CSV: the real files in `../shared/data`, round trips through the writers,
//! and hostile input (truncation at every line and byte, random and flipped bytes).

use std::path::{Path, PathBuf};

use mocap_io::{Capture, Format, FormatError, IoError, ReadOptions, Trajectories, csv, trc};

fn opts() -> ReadOptions {
    ReadOptions::default()
}

fn read_shared(dir: &Path, rel: &str) -> Result<Capture, IoError> {
    mocap_io::read_capture(&dir.join(rel), &opts())
}

/// splitmix64: a seeded generator, so failures reproduce without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A fresh folder for one test's files, named for it and this process (remove it at the end).
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Whether some warning of the capture says `text`.
fn warned(c: &Capture, text: &str) -> bool {
    c.info.warnings.iter().any(|w| w.contains(text))
}

/// A small capture with gaps, negative coordinates and a label with spaces and `_x`.
fn sample_trajectories(seed: u64, markers: usize, frames: usize) -> Trajectories {
    let mut rng = Rng(seed);
    let labels: Vec<String> = (0..markers)
        .map(|m| match m % 3 {
            0 => format!("M{m}"),
            1 => format!("left knee {m}"),
            _ => format!("L_ANK_{m}_x"),
        })
        .collect();
    let positions = (0..markers * frames)
        .map(|_| {
            if rng.below(7) == 0 {
                mocap_io::MISSING
            } else {
                [
                    (rng.unit() - 0.5) * 4000.0,
                    (rng.unit() - 0.5) * 4000.0,
                    rng.unit() * 2000.0,
                ]
            }
        })
        .collect();
    Trajectories::new(labels, 120.0, 37, frames, positions).unwrap()
}

/// Same labels, timing and missing samples; positions within `tol` millimetres.
fn assert_close(a: &Trajectories, b: &Trajectories, tol: f64) {
    assert_eq!(a.labels(), b.labels());
    assert_eq!(a.frame_rate(), b.frame_rate());
    assert_eq!(a.first_frame(), b.first_frame());
    assert_eq!(a.frames(), b.frames());
    for (i, (p, q)) in a.positions().iter().zip(b.positions()).enumerate() {
        assert_eq!(
            mocap_io::is_present(*p),
            mocap_io::is_present(*q),
            "sample {i}"
        );
        if mocap_io::is_present(*p) {
            for k in 0..3 {
                assert!((p[k] - q[k]).abs() <= tol, "sample {i}: {p:?} vs {q:?}");
            }
        }
    }
}

fn close(p: [f64; 3], q: [f64; 3], tol: f64) -> bool {
    (0..3).all(|k| (p[k] - q[k]).abs() <= tol)
}

#[test]
fn opensim_walk_reads() {
    let Some(dir) = mocap_io::testdata::shared_data_dir("opensim_walk_reads") else {
        return;
    };
    let c = read_shared(&dir, "trc/opensim/subject01_walk1.trc").unwrap();
    let t = &c.trajectories;
    assert_eq!(c.format, Format::Trc);
    assert_eq!(t.markers(), 41);
    assert_eq!(t.labels()[0], "R.ASIS");
    assert_eq!(t.labels()[2], "V.Sacral");
    assert_eq!(t.labels()[40], "Top.Head");
    assert_eq!(
        (t.frames(), t.first_frame(), t.frame_rate()),
        (151, 1, 60.0)
    );
    assert_eq!(t.missing_samples(), 0);
    assert_eq!(c.info.declared_units.as_deref(), Some("mm"));
    assert!(c.info.warnings.is_empty(), "{:?}", c.info.warnings);
    // Line 7 of the file: `1  0.000000  617.247620  1055.275020  170.781980  639.606380 ...`.
    assert_eq!(t.get(0, 0), Some([617.247620, 1055.275020, 170.781980]));
    assert_eq!(t.get(0, 1).map(|p| p[0]), Some(639.606380));
    // Last line: `151  2.500000  597.613650  1045.068850  169.864320 ...`.
    assert_eq!(t.get(150, 0), Some([597.613650, 1045.068850, 169.864320]));
}

#[test]
fn btk_res16bits_reads() {
    let Some(dir) = mocap_io::testdata::shared_data_dir("btk_res16bits_reads") else {
        return;
    };
    let c = read_shared(&dir, "trc/btk/Res16bits.trc").unwrap();
    let t = &c.trajectories;
    assert_eq!(t.markers(), 44);
    assert_eq!(&t.labels()[..3], ["R.TETE", "L.TETE", "C7"]);
    assert_eq!(
        (t.frames(), t.first_frame(), t.frame_rate()),
        (100, 1, 100.0)
    );
    assert_eq!(c.info.declared_units.as_deref(), Some("mm"));
    assert!(c.info.warnings.is_empty(), "{:?}", c.info.warnings);
    assert_eq!(t.get(0, 0), Some([221.49382, -284.70554, 1509.52161]));
    // Gaps are empty fields: marker 20 at frames 6 and 24, marker 8 at frames 84–86.
    assert_eq!(t.missing_samples(), 5);
    for (frame, marker) in [(5, 19), (23, 19), (83, 7), (84, 7), (85, 7)] {
        assert_eq!(
            t.get(frame, marker),
            None,
            "frame index {frame}, marker {marker}"
        );
    }
    // The middle frame agrees with the C3D reference values of the same capture.
    assert!(close(
        t.get(50, 0).unwrap(),
        [248.055, -299.675, 1509.608],
        1e-3
    ));
}

#[test]
fn btk_gait_reads_the_named_markers() {
    let Some(dir) = mocap_io::testdata::shared_data_dir("btk_gait_reads_the_named_markers") else {
        return;
    };
    // 66 markers declared, 33 named, ragged rows with unnamed values past both: BTK
    // reads the 33 named markers, and so do we, saying what was ignored.
    let c = read_shared(&dir, "trc/btk/Gait.trc").unwrap();
    let t = &c.trajectories;
    assert_eq!(t.markers(), 33);
    assert_eq!(t.labels()[0], "R.Shoulder");
    assert_eq!(t.labels()[32], "PX");
    assert_eq!(
        (t.frames(), t.first_frame(), t.frame_rate()),
        (487, 1, 100.0)
    );
    // Line 200: `195  1.940  1374.63660  111.01440  1376.84998 ...`.
    assert_eq!(t.get(194, 0), Some([1374.63660, 111.01440, 1376.84998]));
    assert_eq!(t.get(0, 0), None);
    let warnings = c.info.warnings.join("\n");
    assert!(warnings.contains("NumMarkers says 66"), "{warnings}");
    assert!(warnings.contains("past the 33 named markers"), "{warnings}");
}

#[test]
fn btk_bad_files_error_clearly() {
    let Some(dir) = mocap_io::testdata::shared_data_dir("btk_bad_files_error_clearly") else {
        return;
    };
    let e = read_shared(&dir, "bad/Empty.trc").unwrap_err().to_string();
    assert!(
        e.contains("Empty.trc") && e.contains("line 1") && e.contains("empty"),
        "{e}"
    );
    let e = read_shared(&dir, "bad/Truncated.trc")
        .unwrap_err()
        .to_string();
    assert!(e.contains("Truncated.trc") && e.contains("line 3"), "{e}");
    assert!(e.contains("file ends before"), "{e}");
}

#[test]
fn res16bits_trc_agrees_with_its_c3d() {
    let Some(dir) = mocap_io::testdata::shared_data_dir("res16bits_trc_agrees_with_its_c3d") else {
        return;
    };
    let trc = read_shared(&dir, "trc/btk/Res16bits.trc")
        .unwrap()
        .trajectories;
    let c3d = read_shared(&dir, "c3d/btk/Res16bits.c3d")
        .unwrap()
        .trajectories;
    // Labels differ between the two exports (`R.TETE` vs `RTET`); the order is the same.
    assert_eq!(trc.markers(), c3d.markers());
    assert_eq!(
        (trc.frames(), trc.first_frame(), trc.frame_rate()),
        (c3d.frames(), c3d.first_frame(), c3d.frame_rate())
    );
    let mut worst = 0.0f64;
    for f in 0..trc.frames() {
        for m in 0..trc.markers() {
            match (trc.get(f, m), c3d.get(f, m)) {
                (Some(p), Some(q)) => {
                    for k in 0..3 {
                        worst = worst.max((p[k] - q[k]).abs());
                    }
                }
                (None, None) => {}
                (p, q) => panic!("frame {f} marker {m}: TRC {p:?} vs C3D {q:?}"),
            }
        }
    }
    eprintln!("Res16bits: TRC and C3D differ by at most {worst:.2e} mm");
    assert!(worst <= 0.2, "TRC and C3D differ by up to {worst} mm");
}

#[test]
fn real_trc_round_trips_through_the_writer() {
    let Some(dir) = mocap_io::testdata::shared_data_dir("real_trc_round_trips_through_the_writer")
    else {
        return;
    };
    for rel in ["trc/opensim/subject01_walk1.trc", "trc/btk/Res16bits.trc"] {
        let t = read_shared(&dir, rel).unwrap().trajectories;
        let again = trc::parse(trc::write(&t).as_bytes(), &opts()).unwrap();
        assert_close(&t, &again.trajectories, 5.000001e-6);
        let again = csv::parse(csv::write(&t).as_bytes(), &opts()).unwrap();
        assert_close(&t, &again.trajectories, 5.000001e-6);
    }
}

#[test]
fn trc_round_trips_with_gaps_crlf_and_spaces() {
    let t = sample_trajectories(1, 7, 40);
    assert!(t.missing_samples() > 0);
    let text = trc::write(&t);
    let c = trc::parse(text.as_bytes(), &opts()).unwrap();
    assert_close(&t, &c.trajectories, 5e-6);
    assert!(c.info.warnings.is_empty(), "{:?}", c.info.warnings);
    let crlf = text.replace('\n', "\r\n");
    assert_close(
        &t,
        &trc::parse(crlf.as_bytes(), &opts()).unwrap().trajectories,
        5e-6,
    );

    // Space-separated TRC cannot hold empty fields, so only a gap-free capture, with
    // labels without spaces, survives that layout.
    let full = Trajectories::new(
        vec!["A".into(), "B".into()],
        50.0,
        1,
        2,
        vec![
            [1.0, 2.0, 3.0],
            [4.0, 5.0, 6.0],
            [7.0, 8.0, 9.0],
            [10.0, 11.0, 12.0],
        ],
    )
    .unwrap();
    let spaced = trc::write(&full).replace('\t', "   ");
    assert_close(
        &full,
        &trc::parse(spaced.as_bytes(), &opts()).unwrap().trajectories,
        5e-6,
    );
}

#[test]
fn csv_round_trips_with_gaps_and_crlf() {
    let t = sample_trajectories(2, 5, 30);
    let text = csv::write(&t);
    assert!(text.starts_with("# frame_rate: 120\n# units: mm\nframe,M0_x,M0_y,M0_z,"));
    let c = csv::parse(text.as_bytes(), &opts()).unwrap();
    assert_close(&t, &c.trajectories, 5e-6);
    assert!(c.info.warnings.is_empty(), "{:?}", c.info.warnings);
    let crlf = text.replace('\n', "\r\n");
    assert_close(
        &t,
        &csv::parse(crlf.as_bytes(), &opts()).unwrap().trajectories,
        5e-6,
    );
}

#[test]
fn files_round_trip_through_read_capture() {
    let dir = scratch("ossify-trc-csv");
    let t = sample_trajectories(3, 4, 10);
    let trc_path: PathBuf = dir.join("walk.trc");
    let csv_path: PathBuf = dir.join("walk.csv");
    mocap_io::write_trc(&trc_path, &t).unwrap();
    mocap_io::write_csv(&csv_path, &t).unwrap();
    let a = mocap_io::read_capture(&trc_path, &opts()).unwrap();
    let b = mocap_io::read_capture(&csv_path, &opts()).unwrap();
    assert_eq!((a.format, b.format), (Format::Trc, Format::Csv));
    assert_close(&t, &a.trajectories, 5e-6);
    assert_close(&t, &b.trajectories, 5e-6);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn malformed_inputs_name_the_line() {
    let cases: [(&str, &str, &str); 6] = [
        ("", "line 1", "empty"),
        (
            "PathFileType\t4\t(X/Y/Z)\tx.trc\n",
            "line 2",
            "file ends before",
        ),
        (
            "PathFileType\t4\nDataRate\tNumMarkers\n100\t0\nFrame#\tTime\n1\t0\n",
            "line 4",
            "no marker labels",
        ),
        (
            "PathFileType\t4\nDataRate\tNumMarkers\n100\t1\nFrame#\tTime\tA\n1\t0\t1\t2\n2\t0.01\t1\t2\t3e\n",
            "line 6, field 5",
            "`3e` is not a number",
        ),
        (
            "PathFileType\t4\nDataRate\tNumMarkers\n100\t1\nFrame#\tTime\tA\nX1\tY1\tZ1\none\t0\t1\t2\t3\n",
            "line 6, field 1",
            "not an integer",
        ),
        (
            "PathFileType\t4\nDataRate\tNumMarkers\tUnits\n100\t1\tfurlong\n",
            "line 3, field 3",
            "unknown units",
        ),
    ];
    for (text, location, problem) in cases {
        let e: FormatError = trc::parse(text.as_bytes(), &opts()).unwrap_err();
        assert_eq!(e.location, location, "{text:?}: {e}");
        assert!(e.problem.contains(problem), "{text:?}: {e}");
    }
    let csv_cases: [(&str, &str, &str); 4] = [
        ("", "line 1", "empty"),
        (
            "# frame_rate: 60\n",
            "line 1",
            "file ends before the header row",
        ),
        ("# frame_rate: 60\nframe\n", "line 2", "no marker columns"),
        (
            "# frame_rate: 60\nframe,A_x,A_y,A_z\n1,2,3,4\n2,x,,\n",
            "line 4, field 2",
            "`x`",
        ),
    ];
    for (text, location, problem) in csv_cases {
        let e = csv::parse(text.as_bytes(), &opts()).unwrap_err();
        assert_eq!(e.location, location, "{text:?}: {e}");
        assert!(e.problem.contains(problem), "{text:?}: {e}");
    }
}

/// Every prefix that ends at a line boundary or inside the header, and every byte
/// prefix of a small file: a capture or an error naming a line, never a panic.
#[test]
fn truncation_at_every_line_and_byte_never_panics() {
    let t = sample_trajectories(4, 3, 6);
    for (name, text) in [("trc", trc::write(&t)), ("csv", csv::write(&t))] {
        let bytes = text.as_bytes();
        for end in 0..=bytes.len() {
            let prefix = &bytes[..end];
            let result = if name == "trc" {
                trc::parse(prefix, &opts())
            } else {
                csv::parse(prefix, &opts())
            };
            match result {
                Ok(c) => assert!(c.trajectories.frames() <= t.frames()),
                Err(e) => assert!(e.location.starts_with("line "), "{name} at {end}: {e}"),
            }
        }
    }
}

#[test]
fn random_and_flipped_bytes_never_panic() {
    let mut rng = Rng(0x05_51F7);
    let t = sample_trajectories(5, 4, 8);
    let seeds = [trc::write(&t).into_bytes(), csv::write(&t).into_bytes()];
    let alphabet = b"0123456789.-+eE \t\r\n,#_xyzXYZnaNFrame#TimePathFileTypeDataRateUnitsmcm:";
    for round in 0..1500 {
        let bytes: Vec<u8> = match round % 3 {
            // Pure noise.
            0 => (0..rng.below(400)).map(|_| rng.next() as u8).collect(),
            // Plausible characters in random order.
            1 => (0..rng.below(400))
                .map(|_| alphabet[rng.below(alphabet.len())])
                .collect(),
            // A valid file with a few bytes flipped, inserted or removed.
            _ => {
                let mut b = seeds[rng.below(2)].clone();
                for _ in 0..1 + rng.below(4) {
                    let at = rng.below(b.len());
                    match rng.below(3) {
                        0 => b[at] = alphabet[rng.below(alphabet.len())],
                        1 => b.insert(at, rng.next() as u8),
                        _ => {
                            b.remove(at);
                        }
                    }
                }
                b
            }
        };
        for result in [trc::parse(&bytes, &opts()), csv::parse(&bytes, &opts())] {
            match result {
                Ok(c) => {
                    let tr = &c.trajectories;
                    assert_eq!(tr.positions().len(), tr.frames() * tr.markers());
                    assert!(tr.frame_rate() > 0.0);
                }
                Err(e) => assert!(e.location.starts_with("line "), "round {round}: {e}"),
            }
        }
    }
}

/// `frames` and `exclude_markers` cut a capture as it is read: the kept frames keep their
/// numbers and samples, the left-out markers are gone, and both say so in the warnings.
#[test]
fn a_frame_range_and_left_out_markers_are_read_as_asked() {
    let dir = scratch("ossify-select");
    // Frames 37..=46, labels M0, "left knee 1", L_ANK_2_x, M3.
    let t = sample_trajectories(5, 4, 10);
    let path = dir.join("walk.trc");
    mocap_io::write_trc(&path, &t).unwrap();
    let options = ReadOptions {
        frames: Some([40, 44]),
        exclude_markers: vec!["left knee 1".into()],
        ..ReadOptions::default()
    };
    let c = mocap_io::read_capture(&path, &options).unwrap();
    let cut = &c.trajectories;
    assert_eq!((cut.first_frame(), cut.frames()), (40, 5));
    assert_eq!(cut.labels(), ["M0", "L_ANK_2_x", "M3"]);
    let whole = mocap_io::read_capture(&path, &opts()).unwrap().trajectories;
    for f in 0..5 {
        for (k, m) in [0, 2, 3].into_iter().enumerate() {
            let (a, b) = (cut.get(f, k), whole.get(f + 3, m));
            assert_eq!(a.is_some(), b.is_some(), "frame {f} marker {m}");
            if let (Some(a), Some(b)) = (a, b) {
                assert_eq!(a, b);
            }
        }
    }
    let said = c.info.warnings.join("\n");
    assert!(said.contains("read frames 40 to 44 of 37 to 46"), "{said}");
    assert!(said.contains("left out 1 of 4 markers"), "{said}");
    // `*` stands for any run of characters.
    let pattern = ReadOptions {
        exclude_markers: vec!["M*".into()],
        ..ReadOptions::default()
    };
    let c = mocap_io::read_capture(&path, &pattern).unwrap();
    assert_eq!(c.trajectories.labels(), ["left knee 1", "L_ANK_2_x"]);
    let said = c.info.warnings.join("\n");
    assert!(
        said.contains("left out 2 of 4 markers (mocap-io.exclude_markers): M0, M3"),
        "{said}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A range the capture does not hold, a backwards one, an unknown label and leaving out
/// every marker are errors naming the file and the option, never a silent clip.
#[test]
fn a_selection_the_capture_cannot_give_is_an_error() {
    let dir = scratch("ossify-select-bad");
    let t = sample_trajectories(6, 3, 10);
    let path = dir.join("walk.trc");
    mocap_io::write_trc(&path, &t).unwrap();
    let frames = |first, last| ReadOptions {
        frames: Some([first, last]),
        ..ReadOptions::default()
    };
    let excluding = |labels: &[&str]| ReadOptions {
        exclude_markers: labels.iter().map(|l| l.to_string()).collect(),
        ..ReadOptions::default()
    };
    let all: Vec<&str> = t.labels().iter().map(String::as_str).collect();
    let cases: [(ReadOptions, &str); 6] = [
        (
            frames(30, 40),
            "mocap-io.frames: frames 30 to 40 are not all in the capture: it holds frames 37 to 46",
        ),
        (
            frames(44, 40),
            "the first frame 44 comes after the last, 40",
        ),
        (
            excluding(&["M9"]),
            "mocap-io.exclude_markers: the capture has no marker labelled \"M9\" (its 3 markers",
        ),
        (
            excluding(&["Q*"]),
            "no marker of the capture matches \"Q*\"",
        ),
        (excluding(&["m0"]), "did you mean \"M0\"?"),
        (excluding(&all), "it leaves out every marker"),
    ];
    for (options, expected) in cases {
        let error = mocap_io::read_capture(&path, &options)
            .unwrap_err()
            .to_string();
        assert!(error.contains(expected), "{error}");
        assert!(error.contains("walk.trc"), "{error}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A small capture (`sample_trajectories(seed, 3, 6)`) written in millimetres as a TRC and
/// as a CSV into a scratch folder `name`: (the folder, the capture, the TRC, the CSV).
fn walk_in_millimetres(name: &str, seed: u64) -> (PathBuf, Trajectories, PathBuf, PathBuf) {
    let dir = scratch(name);
    let t = sample_trajectories(seed, 3, 6);
    let trc_path = dir.join("walk.trc");
    let csv_path = dir.join("walk.csv");
    mocap_io::write_trc(&trc_path, &t).unwrap();
    mocap_io::write_csv(&csv_path, &t).unwrap();
    (dir, t, trc_path, csv_path)
}

/// `mocap-io.units` overrides a TRC's or CSV's declared units (even one we do not know),
/// or the millimetres assumed where none is declared, and says so; the declared unit
/// itself gives no warning.
#[test]
fn a_unit_option_overrides_what_the_file_declares() {
    let (dir, t, trc_path, csv_path) = walk_in_millimetres("ossify-units", 8);
    let with = |units| ReadOptions {
        units: Some(units),
        ..ReadOptions::default()
    };
    let metres = with(mocap_io::LengthUnit::M);
    for path in [&trc_path, &csv_path] {
        let read = mocap_io::read_capture(path, &metres).unwrap();
        for (a, b) in read.trajectories.positions().iter().zip(t.positions()) {
            for k in 0..3 {
                assert!(
                    a[k].is_nan() && b[k].is_nan() || (a[k] - 1000.0 * b[k]).abs() < 1e-2,
                    "{a:?} {b:?}"
                );
            }
        }
        assert!(
            warned(
                &read,
                "read as m (mocap-io.units), not as the file's \"mm\""
            ),
            "{:?}",
            read.info.warnings
        );
        let declared = mocap_io::read_capture(path, &with(mocap_io::LengthUnit::Mm)).unwrap();
        assert!(!warned(&declared, "mocap-io.units"));
    }
    // The CSV with its units line replaced.
    let variant = |name: &str, units_line: &str| {
        let text = std::fs::read_to_string(&csv_path).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, text.replace("# units: mm\n", units_line)).unwrap();
        path
    };
    // A unit the reader does not know is an error without the option, read with it.
    let odd = variant("odd.csv", "# units: furlong\n");
    assert!(mocap_io::read_capture(&odd, &opts()).is_err());
    let read = mocap_io::read_capture(&odd, &with(mocap_io::LengthUnit::Cm)).unwrap();
    assert!(warned(&read, "not as the file's \"furlong\""));
    // Where the file declares no units (millimetres assumed), the option says so.
    let bare = variant("bare.csv", "");
    let plain = mocap_io::read_capture(&bare, &opts()).unwrap();
    let read = mocap_io::read_capture(&bare, &metres).unwrap();
    assert_eq!(plain.info.declared_units, None);
    let (a, b) = (
        read.trajectories.positions(),
        plain.trajectories.positions(),
    );
    let k = (0..a.len()).find(|&k| !b[k][0].is_nan()).unwrap();
    assert!((a[k][0] - 1000.0 * b[k][0]).abs() < 1e-6 * b[k][0].abs().max(1.0));
    assert!(
        warned(
            &read,
            "read as m (mocap-io.units); the file declares no units"
        ),
        "{:?}",
        read.info.warnings
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// TRC and CSV take the units words C3D does (OpenSim's TRC files may say `in`): a file
/// written in millimetres and relabelled reads scaled by the unit's millimetres, and a word
/// no reader knows is refused with the words it knows.
#[test]
fn every_format_takes_the_same_units_words() {
    let (dir, t, trc_path, csv_path) = walk_in_millimetres("ossify-unit-words", 9);
    let relabel = |path: &Path, units: &str| {
        let text = std::fs::read_to_string(path).unwrap();
        let text = if path == csv_path.as_path() {
            text.replace("# units: mm\n", &format!("# units: {units}\n"))
        } else {
            text.replace("\tmm\t", &format!("\t{units}\t"))
        };
        let out = dir.join(format!(
            "{units}-{}",
            path.file_name().unwrap().to_string_lossy()
        ));
        std::fs::write(&out, text).unwrap();
        out
    };
    for path in [&trc_path, &csv_path] {
        for (units, mm) in [
            ("in", 25.4),
            ("inches", 25.4),
            ("dm", 100.0),
            ("Metres", 1000.0),
        ] {
            let read = mocap_io::read_capture(&relabel(path, units), &opts()).unwrap();
            for (a, b) in read.trajectories.positions().iter().zip(t.positions()) {
                for k in 0..3 {
                    assert!(
                        a[k].is_nan() && b[k].is_nan() || (a[k] - mm * b[k]).abs() < 1e-2,
                        "{units}: {a:?} {b:?}"
                    );
                }
            }
        }
        let err = mocap_io::read_capture(&relabel(path, "furlong"), &opts()).unwrap_err();
        assert!(err.to_string().contains("mm, cm, dm, m or in"), "{err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A units line that does not match the numbers is said, with the unit that fits: a
/// body's markers (a median 75 mm from the nearest) written in metres under `mm` lie
/// 0.075 mm apart as read, and in millimetres under `m` 75 m apart; read in their own
/// unit, nothing is said.
#[test]
fn a_units_line_the_numbers_contradict_is_said_with_the_unit_that_fits() {
    let dir = scratch("ossify-units-implausible");
    // Four markers of one body, 60-150 mm apart, turning slowly.
    let body = [
        [0.0, 0.0, 0.0],
        [60.0, 0.0, 0.0],
        [0.0, 90.0, 0.0],
        [0.0, 0.0, 150.0],
    ];
    let frames = 20;
    let positions: Vec<[f64; 3]> = (0..frames)
        .flat_map(|f| {
            let (s, c) = (0.02 * f as f64).sin_cos();
            body.map(|[x, y, z]| [c * x - s * y + 500.0, s * x + c * y, z + 900.0])
        })
        .collect();
    let labels = ["A", "B", "C", "D"].map(String::from).to_vec();
    let mm = Trajectories::new(labels.clone(), 100.0, 1, frames, positions.clone()).unwrap();
    let in_metres = positions.iter().map(|p| p.map(|x| x / 1000.0)).collect();
    let m = Trajectories::new(labels, 100.0, 1, frames, in_metres).unwrap();
    let path = dir.join("body.trc");
    let read = |t: &Trajectories, units: &str| {
        let text = trc::write(t).replace("\tmm\t", &format!("\t{units}\t"));
        std::fs::write(&path, text).unwrap();
        mocap_io::read_capture(&path, &opts()).unwrap()
    };
    let metres_as_mm = read(&m, "mm");
    assert!(
        warned(
            &metres_as_mm,
            "0.075 mm from their nearest neighbour as read, closer together than in any"
        ) && warned(
            &metres_as_mm,
            "--set mocap-io.units=m reads them so (75.0 mm apart)"
        ),
        "{:?}",
        metres_as_mm.info.warnings
    );
    let mm_as_metres = read(&mm, "m");
    assert!(
        warned(&mm_as_metres, "farther apart than in any marker set")
            && warned(
                &mm_as_metres,
                "--set mocap-io.units=mm reads them so (75.0 mm apart)"
            ),
        "{:?}",
        mm_as_metres.info.warnings
    );
    for (t, units) in [(&mm, "mm"), (&m, "m")] {
        let right = read(t, units);
        assert!(
            !warned(&right, "units look wrong"),
            "{:?}",
            right.info.warnings
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
