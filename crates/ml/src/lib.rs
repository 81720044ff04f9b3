//! Machine learning of the parking brake monitor: the paper's three classifiers and the int8
//! network the core runs, their training ([`train`], on [`nn`]) and evaluation ([`evaluate`]).
#![deny(missing_docs)]

pub mod evaluate;
pub mod nn;
pub mod train;
