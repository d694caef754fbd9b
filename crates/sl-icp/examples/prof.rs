use sl_icp::*;
#[path = "../tests/support/bunny.rs"]
mod bunny;
const N: usize = 3;
fn main() {
    let dir = bunny::bunny_dir("x").unwrap();
    let target = bunny::load(&dir, "bun000");
    let source = bunny::load(&dir, "bun045");
    let reference = bunny::reference(&target, &source);
    let start = bunny::perturbed(&reference, &source.cloud.centroid().unwrap());
    let what = std::env::args().nth(1).unwrap();
    let prep = PrepareConfig {
        voxel_size: Some(1.0),
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    if what == "prep" {
        for _ in 0..N {
            let _ = PreparedCloud::new(&target.cloud, &prep).unwrap();
        }
    } else {
        let s = PreparedCloud::new(&source.cloud, &prep).unwrap();
        let t = PreparedCloud::new(&target.cloud, &prep).unwrap();
        for _ in 0..N {
            let _ = register(&s, &t, &start, &IcpConfig::default()).unwrap();
        }
    }
    println!("{:?} per run", t0.elapsed() / N as u32);
}
