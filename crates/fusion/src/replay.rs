//! The one replay driver: PDR steps and Wi-Fi fixes merged into a single time-ordered input
//! sequence for a [`Fuser`](crate::Fuser).
//!
//! **Tie rule.** At equal timestamps a step comes before a Wi-Fi fix. A step event is stamped
//! with the instant its detection completed, so it describes motion *up to* that instant; a
//! fix describes the position *at* its instant, i.e. after that motion. The same rule holds in
//! a live stream (`wipdr-positioning` feeds the IMU before Wi-Fi at equal times), so a
//! recorded walk replayed here gives exactly what the stream gives. Within one kind, the
//! given order is kept (both slices are expected sorted by time).
//!
//! ```
//! use wipdr_fusion::replay::{FusionInput, merged};
//! use wipdr_fusion::synthetic::{obs_at, step};
//! let steps = [step(1000, 0.7, 0.0), step(2000, 0.7, 0.0)];
//! let fixes = [obs_at(1000, 0.0, 0.0)];
//! let order: Vec<_> = merged(&steps, &fixes).collect();
//! assert_eq!(order, vec![FusionInput::Step(0), FusionInput::Wifi(0), FusionInput::Step(1)]);
//! ```

use crate::{Estimate, Fuser};
use wipdr_core::{StepEvent, TimestampMs, WifiObservation};

/// One input of a replay: the index of a step or of a fix in the slices given to [`merged`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FusionInput {
    /// `steps[i]`.
    Step(usize),
    /// `fixes[j]`.
    Wifi(usize),
}

/// Steps and fixes merged in time order under the module's tie rule (a step before a fix
/// of the same millisecond).
pub fn merged<'a>(
    steps: &'a [StepEvent],
    fixes: &'a [WifiObservation],
) -> impl Iterator<Item = FusionInput> + 'a {
    let (mut i, mut j) = (0usize, 0usize);
    std::iter::from_fn(move || {
        let take_step = match (steps.get(i), fixes.get(j)) {
            (None, None) => return None,
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (Some(s), Some(f)) => s.t <= f.t,
        };
        if take_step {
            i += 1;
            Some(FusionInput::Step(i - 1))
        } else {
            j += 1;
            Some(FusionInput::Wifi(j - 1))
        }
    })
}

/// The time of an input.
pub fn input_time(
    input: FusionInput,
    steps: &[StepEvent],
    fixes: &[WifiObservation],
) -> TimestampMs {
    match input {
        FusionInput::Step(i) => steps[i].t,
        FusionInput::Wifi(j) => fixes[j].t,
    }
}

/// Feeds `steps` and `fixes` to `fuser` in [`merged`] order and calls `on_estimate` after
/// every input with the input, its time and the fuser's estimate (when it has one).
pub fn replay<F: Fuser + ?Sized>(
    fuser: &mut F,
    steps: &[StepEvent],
    fixes: &[WifiObservation],
    mut on_estimate: impl FnMut(FusionInput, TimestampMs, Option<Estimate>),
) {
    for input in merged(steps, fixes) {
        let t = match input {
            FusionInput::Step(i) => {
                fuser.on_step(&steps[i]);
                steps[i].t
            }
            FusionInput::Wifi(j) => {
                fuser.on_wifi(&fixes[j]);
                fixes[j].t
            }
        };
        on_estimate(input, t, fuser.estimate());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{obs_at, step};
    use proptest::prelude::*;

    #[test]
    fn step_before_fix_at_equal_times() {
        let steps = [step(0, 0.7, 0.0), step(500, 0.7, 0.0)];
        let fixes = [
            obs_at(0, 0.0, 0.0),
            obs_at(500, 1.0, 0.0),
            obs_at(900, 1.0, 0.0),
        ];
        let order: Vec<_> = merged(&steps, &fixes).collect();
        use FusionInput::*;
        assert_eq!(order, vec![Step(0), Wifi(0), Step(1), Wifi(1), Wifi(2)]);
    }

    proptest! {
        #[test]
        fn merge_is_a_sorted_permutation(
            mut st in proptest::collection::vec(0i64..50, 0..30),
            mut ft in proptest::collection::vec(0i64..50, 0..30),
        ) {
            st.sort_unstable();
            ft.sort_unstable();
            let steps: Vec<_> = st.iter().map(|&t| step(t, 0.7, 0.0)).collect();
            let fixes: Vec<_> = ft.iter().map(|&t| obs_at(t, 0.0, 0.0)).collect();
            let order: Vec<_> = merged(&steps, &fixes).collect();
            prop_assert_eq!(order.len(), steps.len() + fixes.len());
            let times: Vec<_> = order.iter().map(|&x| input_time(x, &steps, &fixes)).collect();
            prop_assert!(times.windows(2).all(|w| w[0] <= w[1]));
            // Ties: no fix directly before a step of the same time.
            for w in order.windows(2) {
                if let (FusionInput::Wifi(j), FusionInput::Step(i)) = (w[0], w[1]) {
                    prop_assert!(fixes[j].t < steps[i].t);
                }
            }
        }
    }
}
