use wipdr_fusion::synthetic::{obs_at, step};
use wipdr_fusion::{BuildContext, SchemeConfig};
fn main() {
    let config = SchemeConfig::default_for("ekf").unwrap();
    let mut fuser = config.build(&BuildContext::default()).unwrap();
    fuser.on_wifi(&obs_at(0, 0.0, 0.0));
    let mut t = 0;
    let start = std::time::Instant::now();
    let mut acc = 0.0;
    for _ in 0..2_000_000 {
        t += 500;
        let y = t as f64 * 0.0014;
        fuser.on_step(&step(t, 0.7, 0.0));
        fuser.on_wifi(&obs_at(t, 0.3, y));
        acc += fuser.estimate().unwrap().position.y;
    }
    println!("{:?} per iter {}", start.elapsed() / 2_000_000, acc);
}
