//! A radio map from sparse records: `(position, [(ap, rssi), ...])`, as a user's own survey
//! gives them (no dense rows, no "not heard" fill to write).

use crate::{ApVocabulary, FingerprintError, RadioMap, RadioMapConfig, ReferencePoint};
use std::collections::BTreeMap;
use wipdr_core::{Bssid, Point2};

impl From<Point2> for ReferencePoint {
    /// A reference point of one scan at `position`, floor and building unknown.
    fn from(position: Point2) -> Self {
        Self {
            position,
            z: None,
            floor: None,
            building: None,
            scans: 1,
        }
    }
}

impl RadioMap {
    /// Builds a map with one reference point per record, in the given order (a record's
    /// point is a [`Point2`] or a full [`ReferencePoint`], with floor and building). The AP columns
    /// are the BSSIDs heard anywhere, ascending; an AP a record does not list is "not heard"
    /// there. An AP listed twice in one record keeps its mean. Positions must be finite and
    /// RSSI values valid (`is_valid_rssi`): otherwise a typed error naming the record.
    ///
    /// ```
    /// use wipdr_core::{Bssid, Point2};
    /// use wipdr_fingerprint::{RadioMap, RadioMapConfig};
    /// let map = RadioMap::from_records(
    ///     [(Point2::new(0.0, 0.0), vec![(Bssid(7), -50.0)]),
    ///      (Point2::new(5.0, 0.0), vec![(Bssid(7), -70.0), (Bssid(9), -60.0)])],
    ///     RadioMapConfig::default(),
    /// ).unwrap();
    /// assert_eq!((map.len(), map.n_aps()), (2, 2));
    /// assert_eq!(map.rss(0, 1), None); // AP 9 not heard at the first point
    /// ```
    pub fn from_records<I, P, S>(
        records: I,
        config: RadioMapConfig,
    ) -> Result<Self, FingerprintError>
    where
        I: IntoIterator<Item = (P, S)>,
        P: Into<ReferencePoint>,
        S: AsRef<[(Bssid, f64)]>,
    {
        let records: Vec<(ReferencePoint, S)> =
            records.into_iter().map(|(p, s)| (p.into(), s)).collect();
        let mut columns: BTreeMap<Bssid, usize> = BTreeMap::new();
        for (_, heard) in &records {
            for (b, _) in heard.as_ref() {
                columns.entry(*b).or_insert(0);
            }
        }
        for (j, c) in columns.values_mut().enumerate() {
            *c = j;
        }
        let vocabulary = ApVocabulary::from_bssids(columns.keys().copied());
        let mut map = RadioMap::new(vocabulary, config);
        for (i, (position, heard)) in records.iter().enumerate() {
            let mut sums = vec![(0.0f64, 0u32); columns.len()];
            for &(b, rssi) in heard.as_ref() {
                if !crate::radio_map::is_valid_rssi(rssi) {
                    return Err(FingerprintError::InvalidInput(format!(
                        "record {i}: RSSI {rssi} of AP {b:?} is not a valid dBm value"
                    )));
                }
                let s = &mut sums[columns[&b]];
                s.0 += rssi;
                s.1 += 1;
            }
            let mean: Vec<Option<f32>> = sums
                .iter()
                .map(|&(sum, n)| (n > 0).then(|| (sum / f64::from(n)) as f32))
                .collect();
            map.push_point(*position, &mean, None)
                .map_err(|e| match e {
                    FingerprintError::InvalidInput(m) => {
                        FingerprintError::InvalidInput(format!("record {i}: {m}"))
                    }
                    other => other,
                })?;
        }
        Ok(map)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_records_name_themselves() {
        let e = RadioMap::from_records(
            [(Point2::new(f64::NAN, 0.0), vec![(Bssid(1), -50.0)])],
            RadioMapConfig::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("record 0"), "{e}");
        let e = RadioMap::from_records(
            [
                (Point2::new(0.0, 0.0), vec![(Bssid(1), -50.0)]),
                (Point2::new(1.0, 0.0), vec![(Bssid(1), f64::NAN)]),
            ],
            RadioMapConfig::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("record 1"), "{e}");
    }

    #[test]
    fn duplicates_average_and_columns_sort() {
        let map = RadioMap::from_records(
            [(
                Point2::new(0.0, 0.0),
                vec![(Bssid(9), -50.0), (Bssid(3), -60.0), (Bssid(9), -70.0)],
            )],
            RadioMapConfig::default(),
        )
        .unwrap();
        assert_eq!(map.vocabulary().bssid(0), Some(Bssid(3)));
        assert_eq!(map.rss(0, 1), Some(-60.0));
        assert_eq!(map.rss(0, 0), Some(-60.0));
    }
}
