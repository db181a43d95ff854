//! The readers against damaged input: valid scene, style, PLY, OBJ, raw-volume and gzip files are
//! mutated (bit flips, byte changes, truncations, splices of one part into another, numbers made
//! huge) and read again. A reader may refuse any of them, but must not panic, and no input may
//! make it allocate more than [`MEMORY_LIMIT`] at once.
//!
//! `cargo test --release --test fuzz` tries a few thousand inputs;
//! `STREAK_FUZZ_CASES=1000000 cargo test --release --test fuzz -- --nocapture` is the long run
//! (it prints how many inputs each reader took and how many it refused).

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use streak::io::obj::MeshFormat;
use streak::io::ply::{parse_ply, parse_ply_mesh};
use streak::io::raw_volume::VoxelType;
use streak::style::Style;
use streak::surfels::{Budget, Mesh, Volume};
use streak::Scene;

/// Counts the bytes held and the most held since the last reset.
struct Counting;

static HELD: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let held = HELD.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
        PEAK.fetch_max(held, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        HELD.fetch_sub(layout.size(), Ordering::Relaxed);
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Most memory one damaged input may take: the inputs are a few kilobytes and every reader
/// bounds what a count in a file may ask for (scenes here within a budget of 10⁵ surfels).
const MEMORY_LIMIT: usize = 256 << 20;

/// Inputs tried per reader unless `STREAK_FUZZ_CASES` says otherwise.
const CASES: usize = 5000;

/// xorshift64*: a fixed sequence, so a failure names a case that can be replayed.
struct Random(u64);

impl Random {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// One to four mutations of `valid`.
fn mutate(valid: &[u8], random: &mut Random) -> Vec<u8> {
    let mut bytes = valid.to_vec();
    for _ in 0..1 + random.below(4) {
        let at = random.below(bytes.len());
        match random.below(6) {
            0 if !bytes.is_empty() => bytes[at] ^= 1 << random.below(8),
            1 if !bytes.is_empty() => bytes[at] = random.next() as u8,
            2 => bytes.truncate(at),
            3 => {
                // A piece of the file copied elsewhere into it.
                let from = random.below(valid.len());
                let len = random.below(64).min(valid.len() - from);
                let piece = valid[from..from + len].to_vec();
                bytes.splice(at..at, piece);
            }
            4 => {
                // A number made huge, negative or not a number.
                let digits: &[u8] = match random.below(5) {
                    0 => b"4294967296",
                    1 => b"99999999999999999999",
                    2 => b"-1",
                    3 => b"1e308",
                    _ => b"nan",
                };
                bytes.splice(at..at, digits.iter().copied());
            }
            _ => {
                let end = (at + random.below(16)).min(bytes.len());
                bytes.drain(at..end);
            }
        }
    }
    bytes
}

/// Feed `cases` mutations of each of `valid` to `read`, checking each for memory; returns how
/// many were refused.
fn fuzz(name: &str, valid: &[Vec<u8>], seed: u64, read: impl Fn(&[u8]) -> bool) -> usize {
    let cases = std::env::var("STREAK_FUZZ_CASES")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(CASES);
    let mut random = Random(seed);
    let mut refused = 0;
    for case in 0..cases {
        let input = mutate(&valid[case % valid.len()], &mut random);
        let before = HELD.load(Ordering::Relaxed);
        PEAK.store(before, Ordering::Relaxed);
        if !read(&input) {
            refused += 1;
        }
        let taken = PEAK.load(Ordering::Relaxed).saturating_sub(before);
        assert!(
            taken <= MEMORY_LIMIT,
            "{name}, case {case} (seed {seed}): {taken} bytes for a {}-byte input",
            input.len()
        );
    }
    println!("{name}: {cases} inputs, {refused} refused");
    refused
}

const SCENE: &str = r#"
background = [0.1, 0.1, 0.1]
[camera]
eye = [0, 0, 5]
target = [0, 0, 0]
fov_y = 40
width = 48
height = 32
[shutter]
open = 0.1
close = 0.9
shape = "tent"
[lighting]
ambient = 0.2
light = [{ direction = [1, 1, 1], intensity = 0.8 }]
[[object]]
name = "ball"
shape = { type = "torus", major = 1.0, minor = 0.3 }
spacing = 0.1
colour = "normal"
[[object.keyframe]]
t = 0.0
rotate = { axis = [0, 1, 0], degrees = 10 }
[[object.keyframe]]
t = 1.0
translate = [0.5, 0, 0]
scale = 1.5
"#;

#[test]
fn scene_files_refuse_damage_without_panic() {
    let budget = Budget::new(100_000).unwrap();
    let refused = fuzz("scene", &[SCENE.as_bytes().to_vec()], 1, |bytes| {
        let text = String::from_utf8_lossy(bytes);
        Scene::parse_within(&text, Path::new("fuzz.toml"), budget).is_ok()
    });
    assert!(refused > 0);
}

#[test]
fn style_files_refuse_damage_without_panic() {
    let styles = Path::new(env!("CARGO_MANIFEST_DIR")).join("styles");
    let valid: Vec<Vec<u8>> = [
        "comet.toml",
        "ink-lines.toml",
        "heat.toml",
        "stroboscopic.toml",
    ]
    .iter()
    .map(|name| std::fs::read(styles.join(name)).unwrap())
    .collect();
    fuzz("style", &valid, 2, |bytes| {
        Style::parse(&String::from_utf8_lossy(bytes), &styles.join("fuzz.toml")).is_ok()
    });
}

/// A small PLY of points with normals, colours and radii, and a face, in each encoding.
fn ply_files() -> Vec<Vec<u8>> {
    let header = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
             property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
             property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float radius\n\
             element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    let vertices = [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let mut ascii = header("ascii").into_bytes();
    for v in vertices {
        writeln!(ascii, "{} {} {} 0 0 1 200 100 50 0.4", v[0], v[1], v[2]).unwrap();
    }
    ascii.extend_from_slice(b"4 0 1 2 3\n");
    let mut files = vec![ascii];
    for (format, big) in [("binary_little_endian", false), ("binary_big_endian", true)] {
        let mut bytes = header(format).into_bytes();
        let float = |bytes: &mut Vec<u8>, v: f32| {
            bytes.extend(if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            });
        };
        for v in vertices {
            for c in v.into_iter().chain([0.0, 0.0, 1.0]) {
                float(&mut bytes, c);
            }
            bytes.extend([200, 100, 50]);
            float(&mut bytes, 0.4);
        }
        bytes.push(4);
        for i in 0..4i32 {
            bytes.extend(if big {
                i.to_be_bytes()
            } else {
                i.to_le_bytes()
            });
        }
        files.push(bytes);
    }
    files
}

#[test]
fn ply_files_refuse_damage_without_panic() {
    let files = ply_files();
    for file in &files {
        assert!(parse_ply(file, Path::new("valid.ply")).is_ok());
    }
    fuzz("ply cloud", &files, 3, |bytes| {
        parse_ply(bytes, Path::new("fuzz.ply")).is_ok()
    });
    fuzz("ply mesh", &files, 4, |bytes| {
        parse_ply_mesh(bytes, Path::new("fuzz.ply")).is_ok()
    });
}

#[test]
fn obj_files_refuse_damage_without_panic() {
    let obj = b"# a square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
        f 1/1/1 2/1/1 3/1/1\nf -4 -2 -1\nf 1//1 3//1 4//1\n"
        .to_vec();
    fuzz("obj", &[obj], 5, |bytes| {
        Mesh::parse(bytes, MeshFormat::Obj, Path::new("fuzz.obj")).is_ok()
    });
}

#[test]
fn raw_volumes_refuse_damage_without_panic() {
    let uint8: Vec<u8> = (0..4 * 4 * 4).map(|i| (i * 37 % 251) as u8).collect();
    let floats: Vec<u8> = (0..4 * 4 * 4)
        .flat_map(|i| (i as f32 * 0.5).to_le_bytes())
        .collect();
    fuzz("raw volume uint8", &[uint8], 6, |bytes| {
        Volume::parse(bytes, [4, 4, 4], VoxelType::Uint8, Path::new("fuzz.raw")).is_ok()
    });
    fuzz("raw volume float32", &[floats], 7, |bytes| {
        Volume::parse(bytes, [4, 4, 4], VoxelType::Float32, Path::new("fuzz.raw")).is_ok()
    });
}

#[test]
fn gzip_files_refuse_damage_without_panic() {
    // The gzip layer is read from files: each case is written to one and read back.
    let dir = std::env::temp_dir().join(format!("streak-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("cloud.ply.gz");
    let valid: Vec<Vec<u8>> = ply_files()
        .iter()
        .map(|file| {
            let mut encoder =
                flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
            encoder.write_all(file).unwrap();
            encoder.finish().unwrap()
        })
        .collect();
    fuzz("gzip", &valid, 8, |bytes| {
        std::fs::write(&path, bytes).unwrap();
        streak::io::ply::read_ply(&path).is_ok()
    });
    std::fs::remove_dir_all(&dir).unwrap();
}
