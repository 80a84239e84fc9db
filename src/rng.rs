//! Seeded random streams: every random number of psns (fixed-pattern maps, temporal noise, seeded
//! scene content) comes from a stream named by its coordinates, so results depend only on the
//! seed and never on threads, shards or restarts.
//!
//! All randomness derives from one `camera_seed: u64`. Every stream is a ChaCha8 generator
//! (`rand_chacha`) whose 256-bit key is built directly from its coordinates, so each row of each
//! map or noise stage has its own independent stream and a frame does not depend on how rows are
//! spread over threads:
//!
//! | key bytes | content |
//! |---|---|
//! | 0..8   | camera seed, u64 LE |
//! | 8..16  | frame index, u64 LE (0 for fixed-pattern maps) |
//! | 16..20 | map id or stage id, u32 LE |
//! | 20..24 | domain, u32 LE: 0 = fixed-pattern map, 1 = temporal noise, 2 = scene (clouds), 3 = dataset parameters |
//! | 24..32 | row, u64 LE |
//!
//! This derivation is covered by a golden test; changing it changes every emulated camera.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

mod chacha8;
pub(crate) use chacha8::Stream;

/// Domain tags of the key.
const DOMAIN_MAP: u32 = 0;
const DOMAIN_FRAME: u32 = 1;
const DOMAIN_SCENE: u32 = 2;
const DOMAIN_DATASET: u32 = 3;

pub(crate) fn key(seed: u64, frame: u64, id: u32, domain: u32, row: u64) -> [u8; 32] {
    let mut k = [0u8; 32];
    k[0..8].copy_from_slice(&seed.to_le_bytes());
    k[8..16].copy_from_slice(&frame.to_le_bytes());
    k[16..20].copy_from_slice(&id.to_le_bytes());
    k[20..24].copy_from_slice(&domain.to_le_bytes());
    k[24..32].copy_from_slice(&row.to_le_bytes());
    k
}

/// Stream of fixed-pattern map `map_id`, row `row`, of camera `seed`.
pub fn map_rng(seed: u64, map_id: u32, row: u64) -> ChaCha8Rng {
    ChaCha8Rng::from_seed(key(seed, 0, map_id, DOMAIN_MAP, row))
}

/// Stream of temporal stage `stage_id`, row `row`, of frame `frame_index` of camera `seed`.
pub fn frame_rng(seed: u64, frame_index: u64, stage_id: u32, row: u64) -> ChaCha8Rng {
    ChaCha8Rng::from_seed(key(seed, frame_index, stage_id, DOMAIN_FRAME, row))
}

/// [`frame_rng`]'s stream as a [`Stream`]: the same numbers, drawn faster (the exact sensor
/// path's row loops).
pub(crate) fn frame_stream(seed: u64, frame_index: u64, stage_id: u32, row: u64) -> Stream {
    Stream::new(key(seed, frame_index, stage_id, DOMAIN_FRAME, row))
}

/// Stream for seeded scene content (soft clouds), `id` distinguishing uses.
pub fn scene_rng(seed: u64, id: u32) -> ChaCha8Rng {
    ChaCha8Rng::from_seed(key(seed, 0, id, DOMAIN_SCENE, 0))
}

/// Stream drawing parameter `param_id` of dataset sample `frame_index` of a dataset with `seed`
/// (`psns dataset`): the draws depend on these three numbers only, never on threads, shards or
/// restarts.
pub fn dataset_rng(seed: u64, frame_index: u64, param_id: u32) -> ChaCha8Rng {
    ChaCha8Rng::from_seed(key(seed, frame_index, param_id, DOMAIN_DATASET, 0))
}
