#pragma once
// The options of the four networks as JSON text: the form in which checkpoints (train/checkpoint.h)
// record the configuration that rebuilds a network. Every field is written under its C++ name.
#include <string>

#include "models/apparel_displacement.h"
#include "models/apparel_segmenter.h"
#include "models/joint_refiner.h"
#include "models/skinning_predictor.h"

namespace amt {

// === Options -> JSON text

/// One JSON object with every field of the options (doubles written exactly, enums by name).
std::string options_to_json(const ApparelSegmenterOptions& options);
std::string options_to_json(const SkinningPredictorOptions& options);
std::string options_to_json(const ApparelDisplacementOptions& options);
std::string options_to_json(const JointRefinerOptions& options);

// === JSON text -> options

/// Parses `text` into `options`. Fields absent from the text keep the value `options` has; an unknown
/// field, a field of the wrong type or text that is not a JSON object throws amt::Error
/// "<source>: options.<field>: expected ..., found ...".
void options_from_json(const std::string& text, const std::string& source, ApparelSegmenterOptions& options);
void options_from_json(const std::string& text, const std::string& source, SkinningPredictorOptions& options);
void options_from_json(const std::string& text, const std::string& source, ApparelDisplacementOptions& options);
void options_from_json(const std::string& text, const std::string& source, JointRefinerOptions& options);

}  // namespace amt
