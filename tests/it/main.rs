//! End-to-end tests: the real `xtask` binary over committed fixtures and shared captures.
//!
//! One integration-test binary (STYLE.md). Each module drives the CLI as a user would and
//! checks the files it writes against ground truth.

mod accuracy;
mod cli;
mod expect;
mod fill;
mod props;
mod real;
mod stationary;
mod support;
mod unlabeled;
mod vendor;
mod vicon;
