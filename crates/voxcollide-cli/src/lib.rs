//! The `voxcollide` command's library: the paper's scenes and scene files run end to end, with
//! progress, offscreen pictures, ParaView files and a summary; implant candidates compared in
//! one report; and the benchmark of every collision backend against its workload's baseline.
//! The binary (`src/main.rs`) is its command line.
#![doc = include_str!("../README.md")]
#![deny(missing_docs)]

pub mod backend; //  `--backend`: the device a command opens, and where a world steps
pub mod bench; //    `voxcollide bench`: every backend against its workload's baseline
pub mod compare; //  `voxcollide compare`: implant candidates through one scene, and the report
pub mod matrix; //   the contact test matrix: every gap, stiffness, volume, spacing and modulus
pub mod output; //   VTK / ParaView files of the bodies
pub mod plots; //    line charts as SVG (compare's report)
pub mod scenario; // a scene run end to end: backend, frames, files, summary
pub mod scene_run; // a scene file run end to end: any bodies and contacts
pub mod view; //     `voxcollide view`: a scene live in a window
