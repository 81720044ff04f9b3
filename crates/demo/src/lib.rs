//! The main job of the parking brake monitor in one run: fleet data, training, evaluation, CAN
//! replay, audit and the self-contained report (`report/index.html`).
#![deny(missing_docs)]

pub mod demo;
