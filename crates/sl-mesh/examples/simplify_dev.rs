//! dev only
use sl_mesh::{PoissonConfig, SimplifyConfig, poisson_reconstruct, simplify};

fn cpu_ms(path: &str) -> f64 {
    let s = std::fs::read_to_string(path).unwrap();
    let f: Vec<&str> = s.rsplit(')').next().unwrap().split_whitespace().collect();
    let ut: f64 = f[11].parse().unwrap();
    let st: f64 = f[12].parse().unwrap();
    (ut + st) * 10.0
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let cloud = sl_cloud::read_ply(std::path::Path::new(&args[1])).unwrap();
    let s = poisson_reconstruct(&cloud, &PoissonConfig::default()).unwrap();
    let n: usize = args.get(2).map(|a| a.parse().unwrap()).unwrap_or(3);
    for _ in 0..n {
        let mut m = s.mesh.clone();
        let c0 = cpu_ms("/proc/self/stat");
        let t = std::time::Instant::now();
        let r = simplify(&mut m, &s.densities, &SimplifyConfig::default()).unwrap();
        let wall = t.elapsed().as_secs_f64() * 1e3;
        let c1 = cpu_ms("/proc/self/stat");
        println!("wall {wall:.0} ms cpu {:.0} ms: {} -> {} vertices, passes {}", c1 - c0, r.vertices_before, r.vertices_after, r.passes);
    }
}
