//! Wi-Fi scans: BSSIDs as 48-bit ids, scan entries and whole scans.

use crate::{CoreError, TimestampMs};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// A BSSID (access point MAC address) packed into the low 48 bits of a `u64`.
///
/// ```
/// use wipdr_core::Bssid;
/// let b: Bssid = "a8:0c:ca:03:9d:d7".parse().unwrap();
/// assert_eq!(b.to_string(), "a8:0c:ca:03:9d:d7");
/// assert!("a8:0c:ca".parse::<Bssid>().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Bssid(pub u64);

impl Bssid {
    /// The largest valid id (48 bits set).
    pub const MAX: u64 = (1 << 48) - 1;

    /// Builds a BSSID from a raw 48-bit value; `None` if wider than 48 bits.
    pub fn from_u64(v: u64) -> Option<Self> {
        (v <= Self::MAX).then_some(Self(v))
    }
}

impl FromStr for Bssid {
    type Err = CoreError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || CoreError::InvalidBssid(s.chars().take(64).collect());
        let mut v: u64 = 0;
        let mut n = 0;
        for part in s.split(':') {
            if part.is_empty() || part.len() > 2 || n == 6 {
                return Err(bad());
            }
            let byte = u8::from_str_radix(part, 16).map_err(|_| bad())?;
            v = (v << 8) | u64::from(byte);
            n += 1;
        }
        if n != 6 {
            return Err(bad());
        }
        Ok(Self(v))
    }
}

impl fmt::Display for Bssid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let b = self.0.to_be_bytes();
        write!(
            f,
            "{:02x}:{:02x}:{:02x}:{:02x}:{:02x}:{:02x}",
            b[2], b[3], b[4], b[5], b[6], b[7]
        )
    }
}

/// One access point heard in a scan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WifiEntry {
    /// The access point.
    pub bssid: Bssid,
    /// Network name as reported (may be empty or odd).
    pub ssid: String,
    /// Received signal strength, dBm.
    pub rssi_dbm: f64,
    /// Channel centre frequency, MHz.
    pub frequency_mhz: u32,
    /// When the phone last saw this AP (Unix ms); often seconds before the scan time.
    pub last_seen_ms: TimestampMs,
}

impl WifiEntry {
    /// An entry with only what a matcher needs: the AP and its RSSI (dBm). The SSID is empty,
    /// the frequency unknown (0) and the last-seen time unknown (`last_seen_ms =
    /// TimestampMs::MAX`, read as "no age known": the staleness filter never drops it). Set
    /// the optional fields with [`WifiEntry::seen_at`], [`WifiEntry::with_ssid`] and
    /// [`WifiEntry::with_frequency_mhz`].
    ///
    /// ```
    /// use wipdr_core::{Bssid, WifiEntry};
    /// let e = WifiEntry::new(Bssid(0x00aa_bbcc_ddee), -61.0);
    /// assert_eq!(e.age_ms(1_000), 0);
    /// let e = e.seen_at(400);
    /// assert_eq!((e.age_ms(1_000), e.ssid.as_str()), (600, ""));
    /// ```
    pub fn new(bssid: Bssid, rssi_dbm: f64) -> Self {
        Self {
            bssid,
            ssid: String::new(),
            rssi_dbm,
            frequency_mhz: 0,
            last_seen_ms: TimestampMs::MAX,
        }
    }

    /// The entry with its last-seen time set (Unix ms).
    pub fn seen_at(mut self, t: TimestampMs) -> Self {
        self.last_seen_ms = t;
        self
    }

    /// The entry with its network name set.
    pub fn with_ssid(mut self, ssid: impl Into<String>) -> Self {
        self.ssid = ssid.into();
        self
    }

    /// The entry with its channel centre frequency set (MHz).
    pub fn with_frequency_mhz(mut self, frequency_mhz: u32) -> Self {
        self.frequency_mhz = frequency_mhz;
        self
    }

    /// Age of the entry relative to the scan time `scan_t` (ms, >= 0 for sane data).
    /// An entry without a last-seen time ([`WifiEntry::new`]) has age 0.
    pub fn age_ms(&self, scan_t: TimestampMs) -> i64 {
        if self.last_seen_ms == TimestampMs::MAX {
            return 0;
        }
        scan_t.saturating_sub(self.last_seen_ms)
    }
}

/// One Wi-Fi scan: all entries that share a timestamp in the trace.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct WifiScan {
    /// Scan time (Unix ms), the first column of the trace lines.
    pub t: TimestampMs,
    /// The APs heard; at most one entry per BSSID.
    pub entries: Vec<WifiEntry>,
}

impl WifiScan {
    /// A scan at time `t` from `(BSSID, RSSI dBm)` readings, each entry last seen at `t`.
    ///
    /// ```
    /// use wipdr_core::{Bssid, WifiScan};
    /// let scan = WifiScan::from_readings(5_000, [(Bssid(1), -50.0), (Bssid(2), -70.0)]);
    /// assert_eq!(scan.entries.len(), 2);
    /// assert_eq!(scan.entries[1].last_seen_ms, 5_000);
    /// assert_eq!(scan.strongest().unwrap().bssid, Bssid(1));
    /// ```
    pub fn from_readings(t: TimestampMs, readings: impl IntoIterator<Item = (Bssid, f64)>) -> Self {
        Self {
            t,
            entries: readings
                .into_iter()
                .map(|(b, r)| WifiEntry::new(b, r).seen_at(t))
                .collect(),
        }
    }

    /// Keeps one entry per BSSID: the most recent (largest `last_seen_ms`, later in the list
    /// on ties). Returns how many duplicates were removed. Entry order is otherwise kept.
    pub fn dedup_keep_most_recent(&mut self) -> usize {
        use std::collections::HashMap;
        let mut best: HashMap<Bssid, usize> = HashMap::with_capacity(self.entries.len());
        for (i, e) in self.entries.iter().enumerate() {
            match best.get_mut(&e.bssid) {
                Some(j) => {
                    if e.last_seen_ms >= self.entries[*j].last_seen_ms {
                        *j = i;
                    }
                }
                None => {
                    best.insert(e.bssid, i);
                }
            }
        }
        let before = self.entries.len();
        if best.len() == before {
            return 0;
        }
        let mut keep = vec![false; before];
        for &i in best.values() {
            keep[i] = true;
        }
        let mut i = 0;
        self.entries.retain(|_| {
            let k = keep[i];
            i += 1;
            k
        });
        before - self.entries.len()
    }

    /// The entry with the strongest RSSI, if any.
    pub fn strongest(&self) -> Option<&WifiEntry> {
        self.entries
            .iter()
            .max_by(|a, b| a.rssi_dbm.total_cmp(&b.rssi_dbm))
    }

    /// Entries no older than `max_age_ms` relative to the scan time.
    pub fn fresh(&self, max_age_ms: i64) -> impl Iterator<Item = &WifiEntry> {
        self.entries
            .iter()
            .filter(move |e| e.age_ms(self.t) <= max_age_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn entry(b: u64, rssi: f64, seen: i64) -> WifiEntry {
        WifiEntry {
            bssid: Bssid(b),
            ssid: String::new(),
            rssi_dbm: rssi,
            frequency_mhz: 2412,
            last_seen_ms: seen,
        }
    }

    #[test]
    fn dedup_keeps_most_recent() {
        let mut s = WifiScan {
            t: 100,
            entries: vec![
                entry(1, -50.0, 10),
                entry(2, -60.0, 20),
                entry(1, -70.0, 30),
            ],
        };
        assert_eq!(s.dedup_keep_most_recent(), 1);
        assert_eq!(s.entries.len(), 2);
        assert_eq!(s.entries[1].rssi_dbm, -70.0);
    }

    #[test]
    fn bssid_rejects_garbage() {
        for bad in [
            "",
            "zz:00:00:00:00:00",
            "00:00:00:00:00:00:00",
            "000:0:0:0:0:0",
            "::::",
        ] {
            assert!(bad.parse::<Bssid>().is_err(), "{bad}");
        }
        assert_eq!("ff:ff:ff:ff:ff:ff".parse::<Bssid>().unwrap().0, Bssid::MAX);
    }

    proptest! {
        #[test]
        fn bssid_roundtrip(v in 0u64..=Bssid::MAX) {
            let b = Bssid(v);
            prop_assert_eq!(b.to_string().parse::<Bssid>().unwrap(), b);
        }
    }
}
