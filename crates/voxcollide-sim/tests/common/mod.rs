//! Helpers shared by the simulator's tests.
#![allow(dead_code)]

pub mod shapes;
