//! # wipdr-analysis — analyses of the data that are not the evaluation protocol
//!
//! Studies of the recorded signals that inform the methods but score no positioning scheme
//! (the accuracy protocol is `wipdr-eval`): [`wifi_stats`], Wi-Fi on the move (paper 002
//! §3.1, eq. 4-5, Fig. 2-3): each access point's refresh rate and loss rate against its mean
//! RSSI, and the least-squares fit of the paper's Refresh Rate model, behind
//! `wipdr wifi-stats`.
//!
//! It takes core types only (walks, scans): the readers are `wipdr-io`'s, the command and its
//! plot are the `wipdr` tool's.

pub mod wifi_stats;
