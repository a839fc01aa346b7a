#pragma once
// Procedural stylized humanoid bodies on the canonical 22-joint skeleton (docs/dataset.md, "What the builder makes"):
// proportions sampled from a seed (chibi to tall, A-pose or T-pose), a closed manifold body surface
// meshed from a smooth union of tapered capsules, and ground-truth body skinning weights.
#include <cstdint>
#include <random>

#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/skeleton.h"

namespace amt {

// === Parameters

/// Proportions of a generated body. `height` is in metres; every other length is a fraction of the
/// height, so that a parameter set describes a style independently of its size. The defaults are an
/// average adult in a T-pose, close to canonical_skeleton(). The "valid" ranges are what
/// validate_body_params accepts; sample_body_params draws from narrower, plausible ranges.
struct BodyParams {
  /// Top of the head above the soles, metres (feet on y = 0). Valid (0, 5]; sampled 0.94 to 1.91.
  float height = 1.70f;
  /// Head height (chin to crown) / height: about 0.13 for an adult, 0.25 for a chibi. Valid [0.05, 0.4].
  float head_ratio = 0.13f;
  /// Head width / head height (depth is 1.1 times the width). Valid [0.5, 1.5].
  float head_aspect = 0.82f;
  /// Chin to shoulder-joint line / height. Valid [0, 0.15].
  float neck_ratio = 0.05f;
  /// Hip-joint height / shoulder-joint height: how much of the body below the neck is legs. Valid [0.3, 0.8].
  float leg_ratio = 0.62f;
  /// Shoulder-to-wrist length / height (the hand adds another 0.35 of it). Valid [0.1, 0.5].
  float arm_ratio = 0.30f;
  /// Scale on the radii of arms, legs, hands and feet (1 = average adult). Valid [0.4, 2.5].
  float limb_thickness = 1.0f;
  /// Distance between the two shoulder joints / height. Valid [0.08, 0.4].
  float shoulder_width = 0.21f;
  /// Distance between the two hip joints / height. Valid [0.04, 0.25].
  float hip_width = 0.105f;
  /// Half-width of the torso at the chest / height. Valid [0.04, 0.2].
  float chest_radius = 0.09f;
  /// Half-width of the torso at the waist (spine2) / height. Valid [0.03, 0.2].
  float waist_radius = 0.072f;
  /// Half-width of the torso at the hips (pelvis) / height. Valid [0.04, 0.2].
  float hip_radius = 0.095f;
  /// Torso depth / torso width (front to back over side to side). Valid [0.4, 1.2].
  float torso_depth = 0.72f;
  /// Rest angle of the arms below the horizontal, degrees: 0 is a T-pose, 25 to 45 an A-pose. Valid [-10, 60].
  float arm_angle_deg = 0.0f;
};

/// Throws amt::Error with a one-line message naming the field when a parameter is NaN, infinite or
/// outside its valid range (see BodyParams).
void validate_body_params(const BodyParams& params);

/// Draws a body from `rng`: a stylisation amount s uniform in [0, 1] moves height, head size, neck,
/// leg length and limb thickness from a tall adult (s = 0) to a chibi (s = 1, about 1 m with a head a
/// quarter of the height), each with its own jitter; torso shape and widths vary independently; half
/// of the bodies stand in a T-pose (0 to 6 degrees), half in an A-pose (25 to 42 degrees). Uses only
/// raw 32-bit draws of the engine, so the result is the same with every standard library.
BodyParams sample_body_params(std::mt19937& rng);

/// The same from a seed (the engine is seeded with its low and high 32-bit words).
BodyParams sample_body_params(uint64_t seed);

// === Generation

/// The canonical skeleton (names and parents of canonical_skeleton()) with rest joints placed from
/// the parameters: feet on y = 0, facing +Z, the body's left on +X, arms at params.arm_angle_deg.
/// rest_joints #22 by 3, metres. Throws like validate_body_params.
Skeleton body_skeleton(const BodyParams& params);

/// Smallest and largest accepted target vertex counts of generate_body.
constexpr int kMinBodyVertices = 1000;
constexpr int kMaxBodyVertices = 200000;

/// A generated body: its parameters, skeleton (= body_skeleton(params)), surface and skinning.
///   mesh: closed, manifold, one connected component, outward-facing (counter-clockwise seen from
///         outside); V #V by 3 metres, soles at y = 0 and crown at y = height (to within a voxel's
///         interpolation error, a few millimetres).
///   weights: #V rows over the 22 canonical joints, at most 4 influences per vertex, rows summing to 1.
///         A joint drives the bone towards its children (the left forearm follows left_elbow), the
///         head, hands and feet follow head, wrists and feet.
struct GeneratedBody {
  BodyParams params;
  Skeleton skeleton;
  TriMesh mesh;
  SparseWeights weights;
};

/// Generates the body of `params` with about `target_vertices` vertices (within 10 %, usually 5 %).
/// The surface is the zero set of a smooth union of tapered capsules and ellipsoids, one or more per
/// bone, sampled in a narrow band of voxels and meshed with OpenVDB's volumeToMesh; the voxel size
/// is corrected until the vertex count matches. Skinning weights fall off smoothly with the distance
/// to each bone's shape, among the joints near the closest bone in the hierarchy, are smoothed over
/// the mesh edges and then cut to 4 influences. Deterministic: the same parameters and thread count
/// give bit-identical results. Throws amt::Error on invalid parameters or a target outside
/// [kMinBodyVertices, kMaxBodyVertices].
GeneratedBody generate_body(const BodyParams& params, int target_vertices);

}  // namespace amt
