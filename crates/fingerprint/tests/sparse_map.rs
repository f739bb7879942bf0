//! The sparse form of a radio map (what a saved site model stores) reads back as the map,
//! and a crafted one (a shape beyond the limit, cells outside the table or repeated) is an
//! error before anything large is allocated.

use proptest::prelude::*;
use wipdr_core::{Bssid, Point2};
use wipdr_fingerprint::radio_map::SparseCell;
use wipdr_fingerprint::{RadioMap, RadioMapConfig};

fn map_of(rows: &[Vec<(u8, i8)>]) -> RadioMap {
    RadioMap::from_records(
        rows.iter().enumerate().map(|(i, heard)| {
            (
                Point2::new(i as f64, 0.5 * i as f64),
                heard
                    .iter()
                    .map(|&(ap, rss)| (Bssid(u64::from(ap) + 1), f64::from(rss) - 20.0))
                    .collect::<Vec<_>>(),
            )
        }),
        RadioMapConfig::default(),
    )
    .unwrap()
}

proptest! {
    #[test]
    fn the_sparse_form_reads_back_as_the_map(
        rows in proptest::collection::vec(
            proptest::collection::vec((0u8..12, -100i8..-10), 1..6), 1..20)
    ) {
        let map = map_of(&rows);
        let cells = map.sparse_cells();
        prop_assert!(cells.len() <= map.len() * map.n_aps());
        let back = RadioMap::from_sparse(
            map.vocabulary().clone(),
            map.points().to_vec(),
            map.config(),
            &cells,
            usize::MAX,
        )
        .unwrap();
        prop_assert_eq!(back, map);
    }
}

#[test]
fn crafted_sparse_maps_are_refused() {
    let map = map_of(&[vec![(0, -50), (1, -60)], vec![(1, -70)]]);
    let parts = || {
        (
            map.vocabulary().clone(),
            map.points().to_vec(),
            map.config(),
        )
    };
    let cell = |point, ap| SparseCell {
        point,
        ap,
        mean_dbm: -50.0,
        count: 1,
        spread_db: 0.0,
    };
    let refused = |cells: &[SparseCell], max: usize| {
        let (v, p, c) = parts();
        RadioMap::from_sparse(v, p, c, cells, max)
            .expect_err("refused")
            .to_string()
    };
    // A shape over the limit is refused before the table is allocated.
    assert!(refused(&[], 3).contains("more than the 3 cells"));
    assert!(refused(&[cell(2, 0)], usize::MAX).contains("outside the table"));
    assert!(refused(&[cell(0, 9)], usize::MAX).contains("outside the table"));
    assert!(refused(&[cell(1, 0), cell(1, 0)], usize::MAX).contains("twice or out of order"));
    assert!(refused(&[cell(1, 0), cell(0, 1)], usize::MAX).contains("twice or out of order"));
}
