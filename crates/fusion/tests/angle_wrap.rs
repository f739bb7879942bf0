//! Angle wrap-around never produces a jump: walking along headings that straddle ±pi (and
//! with Wi-Fi fixes that agree with the walk), every scheme moves by about one step per step
//! in the step's direction.

use proptest::prelude::*;
use wipdr_core::{Point2, angle};
use wipdr_fusion::synthetic::{obs_at, step};
use wipdr_fusion::{BuildContext, SchemeConfig};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    #[test]
    fn no_jump_across_pi(
        headings in prop::collection::vec(
            prop_oneof![std::f64::consts::PI - 0.2..=std::f64::consts::PI,
                        -std::f64::consts::PI..-std::f64::consts::PI + 0.2], 10..60),
        seed in any::<u64>(),
    ) {
        for name in ["pdr", "ekf", "aekf", "akf", "rkf", "arkf", "aws", "tcpf", "pf", "apf"] {
            let config = SchemeConfig::default_for(name).unwrap();
            let ctx = BuildContext { seed, ..BuildContext::default() };
            let mut fuser = config.build(&ctx).unwrap();
            fuser.on_wifi(&obs_at(0, 0.0, 0.0));
            let mut truth = Point2::origin();
            let mut t = 0;
            for (k, h) in headings.iter().enumerate() {
                t += 500;
                let before = fuser.estimate().unwrap().position;
                fuser.on_step(&step(t, 0.7, *h));
                truth += angle::step_displacement(0.7, *h);
                let moved = fuser.estimate().unwrap().position - before;
                // one step, in the step's direction (particle filters: their mean moves by
                // about one step; noise allowed)
                prop_assert!(moved.norm() < 1.5, "{name}: moved {} m", moved.norm());
                if !matches!(name, "pf" | "apf") {
                    prop_assert!(angle::diff(angle::heading_of(moved), *h).abs() < 0.2,
                        "{name}: moved towards {} for heading {}", angle::heading_of(moved), h);
                }
                if k % 3 == 2 {
                    fuser.on_wifi(&obs_at(t, truth.x, truth.y));
                }
            }
            let error = (fuser.estimate().unwrap().position - truth).norm();
            prop_assert!(error < 5.0, "{name}: ended {error} m from the truth");
        }
    }
}
