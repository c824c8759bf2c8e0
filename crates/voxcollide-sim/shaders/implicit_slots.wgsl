// The implicit solve's per-vertex vectors: slots of each body's `work` buffer, `n` entries
// each. Shared by the solve (implicit_solve.wgsl and its stems) and the couplings' passes
// (couple.wgsl, couple_gather.wgsl); keep in sync with SLOTS, SLOT_KC0 and SLOT_E0 in
// src/gpu/implicit.rs.

const SLOT_F: u32 = 0u;      // xyz: the force; w: 1 on a floor row
const SLOT_G: u32 = 1u;      // ∂V/∂x
const SLOT_P0: u32 = 2u;     // the preconditioner's inverse block, by columns
const SLOT_P1: u32 = 3u;
const SLOT_P2: u32 = 4u;
const SLOT_KC0: u32 = 5u;    // the contacts' k·nnᵀ: (xx, yy, zz, xy), (xz, yz, -, -)
const SLOT_KC1: u32 = 6u;
const SLOT_HELD: u32 = 7u;   // the prescribed Δv of pinned and driven vertices
const SLOT_X: u32 = 8u;      // Δv (kept: the next step's guess)
const SLOT_R: u32 = 9u;
const SLOT_Z: u32 = 10u;
const SLOT_P: u32 = 11u;
const SLOT_AP: u32 = 12u;
const SLOT_B: u32 = 13u;
const SLOT_T: u32 = 14u;     // scratch: the new velocity
const SLOT_C: u32 = 15u;     // a surface contact's coupling terms (couple_gather.wgsl)
const SLOT_E0: u32 = 16u;    // the couplings' own blocks for the preconditioner (the host's),
const SLOT_E1: u32 = 17u;    // symmetric as SLOT_KC0/1
const SLOTS: u32 = 18u;
