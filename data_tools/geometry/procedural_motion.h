#pragma once
// Procedural motions on the canonical skeleton: variety that does not depend on mocap files. Walks, runs,
// turns, jumps, spins and dance-like arm and hip motion, each with a few parameters, and seeded variations of
// them for the dataset builder. Every motion is on canonical_skeleton(), faces +Z at frame 0 and stands with
// its feet near y = 0 (root translation is relative to the rest pose).
#include <cstdint>
#include <string>

#include "data_tools/geometry/motion.h"

namespace amt {

// === Motions with parameters

/// A walk cycle on the canonical skeleton: legs swing about the hips with knee bend, arms lowered
/// from the T-pose swing opposite to the legs, the pelvis bobs, and the root travels along +Z at
/// `speed` m/s with one stride every `stride_seconds`. Starts mid-stride at frame 0.
Motion walk_motion(int frames, float fps = 30.0f, float speed = 1.2f, float stride_seconds = 1.1f);

/// A run: wider leg swing with deep knee bend, bent arms pumping, the torso leaning forward, a
/// flight phase (the pelvis rises twice per stride) and the root travelling along +Z at `speed` m/s
/// with one stride (two steps) every `stride_seconds`.
Motion run_motion(int frames, float fps = 30.0f, float speed = 3.0f, float stride_seconds = 0.7f);

/// A walk along a circular arc: the heading turns by `turn_degrees_per_second` (positive turns to the
/// character's left, about +Y) while the root advances at `speed` m/s along the heading.
Motion turn_motion(int frames, float fps = 30.0f, float turn_degrees_per_second = 60.0f, float speed = 1.0f);

/// Repeated jumps in place: a crouch, a take-off with the arms swinging up, a ballistic flight of
/// `height` metres (root height follows g = 9.8 m/s^2), a landing crouch; one jump every
/// `period_seconds` (long enough for the flight: period > 0.5 s + 2 sqrt(2 height / g)).
Motion jump_motion(int frames, float fps = 30.0f, float height = 0.3f, float period_seconds = 1.4f);

/// A spin on the spot: the pelvis turns about +Y at `turns_per_second` (sign gives the direction),
/// ramping up over the first half second, with the arms held out and a slight knee bounce, so that
/// skirts and hair flare out.
Motion spin_motion(int frames, float fps = 30.0f, float turns_per_second = 0.8f);

/// Dance-like motion: hip sway (side-to-side root translation and pelvis roll), torso twist, knee
/// bounce on every beat and the arms waving overhead and to the sides, at `beats_per_minute`, with
/// the amplitudes scaled by `energy` (in [0, 2]; 1 is moderate).
Motion dance_motion(int frames, float fps = 30.0f, float beats_per_minute = 110.0f, float energy = 1.0f);

// === Seeded variations

/// The procedural motion kinds, in the order procedural_motion_set cycles through them.
enum class ProceduralKind : uint8_t { kWalk, kRun, kTurn, kJump, kSpin, kDance };

/// Number of ProceduralKind values.
constexpr int kProceduralKindCount = 6;

/// "walk", "run", "turn", "jump", "spin", "dance".
const char* procedural_kind_name(ProceduralKind kind);

/// A motion of `kind` with parameters drawn from `seed` within plausible ranges (e.g. walks at 0.8 to
/// 1.6 m/s, turns of 30 to 90 degrees per second either way, spins of 0.4 to 1.2 turns per second either
/// way). Deterministic: the same arguments give bit-identical motions on every platform (parameters
/// come from std::mt19937_64 output bits, not from std:: distributions, whose results are unspecified).
Motion random_procedural_motion(ProceduralKind kind, uint64_t seed, int frames, float fps = 30.0f);

}  // namespace amt
