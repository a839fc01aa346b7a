#pragma once
// The options of the four networks as JSON text: the form in which checkpoints (models/checkpoint.h)
// record the configuration that rebuilds a network. Every field is written under its C++ name.
#include <string>

#include "models/apparel_displacement.h"
#include "models/apparel_dynamics.h"
#include "models/apparel_segmenter.h"
#include "models/joint_refiner.h"
#include "models/skinning_predictor.h"

namespace amt {

// === Options -> JSON text

/// One JSON object with every field of the options (doubles written exactly, enums by name).
std::string options_to_json(const ApparelSegmenterOptions& options);
std::string options_to_json(const SkinningPredictorOptions& options);
std::string options_to_json(const ApparelDisplacementOptions& options);
std::string options_to_json(const ApparelDynamicsOptions& options);
std::string options_to_json(const JointRefinerOptions& options);

/// Whether an apparel checkpoint's options JSON is of the local form (ApparelDynamicsNet, whose
/// options always carry `form`) rather than the earlier global one (ApparelDisplacementNet, whose
/// options have no such field).
bool is_local_apparel_options(const std::string& text);

// === JSON text -> options

/// Parses `text` into `options`. Fields absent from the text keep the value `options` has; an unknown
/// field, a field of the wrong type or text that is not a JSON object throws amt::Error
/// "<source>: options.<field>: expected ..., found ...".
void options_from_json(const std::string& text, const std::string& source, ApparelSegmenterOptions& options);
void options_from_json(const std::string& text, const std::string& source, SkinningPredictorOptions& options);
void options_from_json(const std::string& text, const std::string& source, ApparelDisplacementOptions& options);
void options_from_json(const std::string& text, const std::string& source, ApparelDynamicsOptions& options);
void options_from_json(const std::string& text, const std::string& source, JointRefinerOptions& options);

// === Skinning variants (paper Table 4)

/// The name a variant has in options JSON: "geodesic_attention", "no_geodesic" or "sort_by_geodesic".
const char* skinning_variant_name(SkinningVariant variant);

/// The variant named on the command line: "geodesic" (the paper's method), "no_geodesic" or "sorted"
/// (the JSON names are accepted too). Throws amt::Error "<source>: expected geodesic, no_geodesic or
/// sorted, found 'x'".
SkinningVariant parse_skinning_variant(const std::string& name, const std::string& source);

/// The file stem of a trained skinning predictor of that variant, so the three can sit side by side:
/// "skinning", "skinning_no_geodesic", "skinning_sorted" (<stem>.ckpt, <stem>.csv).
std::string skinning_file_stem(SkinningVariant variant);

}  // namespace amt
