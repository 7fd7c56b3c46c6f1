//! Hostile input for the C3D reader: truncation, random bytes, flipped bytes, absurd counts.
//!
//! Every case must end in `Ok` or in an `Err` that says where; none may panic, hang or
//! allocate what the file merely claims.

use std::time::{Duration, Instant};

use mocap_io::{FormatError, ReadOptions, Trajectories, c3d};

/// SplitMix64: a seeded generator small enough to live here.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Parses and checks the outcome is sound: an error says where, a capture is consistent.
fn parse_soundly(bytes: &[u8], what: &str) -> Result<(), FormatError> {
    match c3d::parse(bytes, &ReadOptions::default()) {
        Ok(c) => {
            let t = &c.trajectories;
            assert_eq!(t.positions().len(), t.frames() * t.markers(), "{what}");
            assert!(
                t.positions()
                    .iter()
                    .all(|p| p.iter().all(|v| v.is_finite()) || p.iter().all(|v| v.is_nan())),
                "{what}: a partly missing sample"
            );
            Ok(())
        }
        Err(e) => {
            let l = &e.location;
            assert!(
                l.contains("byte") || l.contains("header") || l.contains("parameter"),
                "{what}: error without a location: {e}"
            );
            assert!(!e.problem.is_empty(), "{what}");
            Err(e)
        }
    }
}

fn written_file() -> Vec<u8> {
    let markers = 9;
    let frames = 40;
    let labels = (0..markers).map(|m| format!("MARK{m}")).collect();
    let positions = (0..markers * frames)
        .map(|i| {
            if i % 11 == 5 {
                mocap_io::MISSING
            } else {
                let t = i as f64 * 0.1;
                [t.sin() * 500.0, t.cos() * 500.0, 900.0 + t]
            }
        })
        .collect();
    let t = Trajectories::new(labels, 100.0, 1, frames, positions).unwrap();
    c3d::write(&t).unwrap()
}

fn real_file(name: &str) -> Option<Vec<u8>> {
    let dir = mocap_io::testdata::shared_data_dir("c3d_hostile")?;
    Some(std::fs::read(dir.join(name)).expect("shared file"))
}

/// Section boundaries of a well-formed file: header end, parameter start, data start, frames.
fn boundaries(bytes: &[u8]) -> Vec<usize> {
    let mut cuts = vec![0, 1, 2, 511, 512, 513];
    let param = (usize::from(bytes[0]).max(1) - 1) * 512;
    cuts.extend([
        param,
        param + 1,
        param + 3,
        param + 4,
        param + 6,
        param + 512,
    ]);
    let data_block = usize::from(u16::from_le_bytes([bytes[16], bytes[17]]));
    let data = data_block.saturating_sub(1) * 512;
    cuts.extend([data - 1, data, data + 1, data + 8, data + 16]);
    cuts.extend([
        bytes.len() - 512,
        bytes.len() - 17,
        bytes.len() - 16,
        bytes.len() - 1,
    ]);
    cuts.retain(|&c| c <= bytes.len());
    cuts
}

fn truncations(bytes: &[u8], name: &str) {
    let mut cuts = boundaries(bytes);
    cuts.extend((0..bytes.len()).step_by(bytes.len() / 400 + 1));
    for cut in cuts {
        let what = format!("{name} cut at byte {cut}");
        let outcome = parse_soundly(&bytes[..cut], &what);
        if cut < 512 {
            assert!(
                outcome.is_err(),
                "{what}: read a file shorter than its header"
            );
        }
    }
}

#[test]
fn truncated_written_file_never_panics() {
    let bytes = written_file();
    assert!(parse_soundly(&bytes, "whole written file").is_ok());
    truncations(&bytes, "written");
}

#[test]
fn truncated_real_files_never_panic() {
    for name in [
        "c3d/c3d.org/sample01/Eb015vr.c3d",
        "c3d/cmu/02_01.c3d",
        "c3d/c3d.org/sample01/Eb015si.c3d",
    ] {
        let Some(bytes) = real_file(name) else {
            return;
        };
        truncations(&bytes, name);
    }
}

#[test]
fn a_truncated_data_section_keeps_the_complete_frames() {
    let bytes = written_file();
    let whole = c3d::parse(&bytes, &ReadOptions::default()).unwrap();
    let data = (usize::from(u16::from_le_bytes([bytes[16], bytes[17]])) - 1) * 512;
    // 9 markers × 16 bytes per frame: cut in the middle of frame index 10.
    let cut = data + 9 * 16 * 10 + 20;
    let part = c3d::parse(&bytes[..cut], &ReadOptions::default()).unwrap();
    assert_eq!(part.trajectories.frames(), 10);
    let debug = |t: &Trajectories| format!("{:?}", t.frame(9)); // NaN != NaN
    assert_eq!(debug(&part.trajectories), debug(&whole.trajectories));
    assert!(
        part.info
            .warnings
            .iter()
            .any(|w| w.contains("complete frames"))
    );
    // Not one complete frame left: refused, naming the data section.
    let e = c3d::parse(&bytes[..data + 100], &ReadOptions::default()).unwrap_err();
    assert!(e.location.contains("data section"), "{e}");
}

#[test]
fn random_bytes_never_panic() {
    let mut rng = Rng(0x05_51f7);
    for case in 0..3000 {
        let len = rng.below(3 * 512);
        let mut bytes: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
        // Half the cases get a plausible start so the parser goes past the first check.
        if case % 2 == 0 && bytes.len() >= 4 {
            bytes[0] = 2;
            bytes[1] = 0x50;
            if bytes.len() > 515 {
                bytes[515] = 84 + (case % 3) as u8;
            }
        }
        let _ = parse_soundly(&bytes, &format!("random case {case}"));
    }
}

fn flip_cases(bytes: &[u8], name: &str, cases: usize, seed: u64) {
    let data = (usize::from(u16::from_le_bytes([bytes[16], bytes[17]])) - 1) * 512;
    let region = data.min(bytes.len());
    let mut rng = Rng(seed);
    let mut copy = bytes.to_vec();
    let start = Instant::now();
    for case in 0..cases {
        copy.copy_from_slice(bytes);
        let flips = 1 + rng.below(4);
        for _ in 0..flips {
            let at = rng.below(region);
            copy[at] = match rng.below(3) {
                0 => copy[at] ^ (1 << rng.below(8)),
                1 => 0xff,
                _ => rng.next() as u8,
            };
        }
        let _ = parse_soundly(&copy, &format!("{name} flip case {case}"));
    }
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "{name}: flips too slow"
    );
}

#[test]
fn flipped_header_and_parameter_bytes_never_panic() {
    flip_cases(&written_file(), "written", 4000, 7);
    if let Some(bytes) = real_file("c3d/c3d.org/sample02/dec_real.c3d") {
        flip_cases(&bytes, "dec_real", 1500, 11);
    }
    if let Some(bytes) = real_file("c3d/c3d.org/sample02/sgi_int.c3d") {
        flip_cases(&bytes, "sgi_int", 1500, 13);
    }
}

/// One parameter for [`crafted`]: group id (1 POINT, 2 TRIAL), name, type, dimensions, data.
type Spec<'a> = (i8, &'a str, i8, &'a [u8], Vec<u8>);

/// A hand-made Intel float file: header, one parameter block, `data_blocks` zero blocks.
fn crafted(points: u16, header_last: u16, params: &[Spec], data_blocks: usize) -> Vec<u8> {
    let mut f = vec![0u8; 512 * (2 + data_blocks)];
    f[0] = 2;
    f[1] = 0x50;
    f[2..4].copy_from_slice(&points.to_le_bytes());
    f[6..8].copy_from_slice(&1u16.to_le_bytes());
    f[8..10].copy_from_slice(&header_last.to_le_bytes());
    f[12..16].copy_from_slice(&(-1.0f32).to_le_bytes());
    f[16..18].copy_from_slice(&3u16.to_le_bytes());
    f[20..24].copy_from_slice(&100.0f32.to_le_bytes());
    let mut p = vec![1, 0x50, 1, 84];
    let mut entry = |name: &str, id: i8, body: &[u8]| {
        p.push(name.len() as u8);
        p.push(id as u8);
        p.extend_from_slice(name.as_bytes());
        let next = (2 + body.len()) as i16;
        p.extend_from_slice(&next.to_le_bytes());
        p.extend_from_slice(body);
    };
    entry("POINT", -1, &[0]);
    entry("TRIAL", -2, &[0]);
    for (group, name, kind, dims, value) in params {
        let mut body = vec![*kind as u8, dims.len() as u8];
        body.extend_from_slice(dims);
        body.extend_from_slice(value);
        body.push(0);
        entry(name, *group, &body);
    }
    f[512..512 + p.len()].copy_from_slice(&p);
    f
}

fn u16_param(name: &str, v: u16) -> Spec<'_> {
    (1, name, 2, &[], v.to_le_bytes().to_vec())
}

#[test]
fn absurd_counts_are_refused_quickly_without_allocating() {
    let start = Instant::now();
    let long = 2f32.powi(31).to_le_bytes().to_vec();
    // 65535 points × 2^31 frames (POINT:LONG_FRAMES) in a 2 KB file.
    let f = crafted(
        65535,
        65535,
        &[
            u16_param("USED", 65535),
            (1, "LONG_FRAMES", 4, &[], long.clone()),
        ],
        2,
    );
    let e = parse_soundly(&f, "absurd").unwrap_err();
    assert!(e.location.contains("data section"), "{e}");
    assert!(e.problem.contains("2147483648 frames"), "{e}");
    // The same claim through the TRIAL fields (32-bit frame numbers, low word first).
    let f = crafted(
        65535,
        65535,
        &[
            u16_param("USED", 65535),
            u16_param("FRAMES", 65535),
            (2, "ACTUAL_START_FIELD", 2, &[2], vec![1, 0, 0, 0]),
            (2, "ACTUAL_END_FIELD", 2, &[2], vec![0, 0, 0, 0x80]),
        ],
        1,
    );
    let e = parse_soundly(&f, "absurd trial").unwrap_err();
    assert!(e.problem.contains("2147483648 frames"), "{e}");
    // Few points but 2^31 frames: the complete frames present are read, with a warning.
    let f = crafted(
        2,
        65535,
        &[u16_param("USED", 2), (1, "LONG_FRAMES", 4, &[], long)],
        2,
    );
    let c = c3d::parse(&f, &ReadOptions::default()).unwrap();
    assert_eq!(c.trajectories.frames(), 1024 / 32);
    assert!(c.info.warnings.iter().any(|w| w.contains("2147483648")));
    assert!(
        start.elapsed() < Duration::from_millis(500),
        "{:?}",
        start.elapsed()
    );
}

#[test]
fn parameter_chains_that_loop_or_point_backwards_end() {
    // A `next` of -6 would point back at the entry itself: the walk stops with a warning.
    let mut f = crafted(1, 1, &[u16_param("USED", 1)], 1);
    // After the POINT and TRIAL groups (10 bytes each) and the "USED" entry's name.
    let used_next = 512 + 4 + 10 + 10 + 2 + 4;
    f[used_next..used_next + 2].copy_from_slice(&(-6i16).to_le_bytes());
    let c = c3d::parse(&f, &ReadOptions::default()).unwrap();
    assert!(
        c.info
            .warnings
            .iter()
            .any(|w| w.contains("next offset is -6")),
        "{:?}",
        c.info.warnings
    );
}

#[test]
fn not_c3d_and_empty_inputs_are_errors_that_say_why() {
    let e = c3d::parse(&[], &ReadOptions::default()).unwrap_err();
    assert!(e.problem.contains("0 bytes"), "{e}");
    let mut f = written_file();
    f[1] = 0x51;
    let e = c3d::parse(&f, &ReadOptions::default()).unwrap_err();
    assert!(
        e.location.contains("byte 1") && e.problem.contains("not a C3D"),
        "{e}"
    );
    let mut f = written_file();
    f[512 + 3] = 99;
    let e = c3d::parse(&f, &ReadOptions::default()).unwrap_err();
    assert!(e.problem.contains("processor"), "{e}");
    let mut f = written_file();
    f[0] = 200;
    let e = c3d::parse(&f, &ReadOptions::default()).unwrap_err();
    assert!(e.problem.contains("past the end"), "{e}");
}
