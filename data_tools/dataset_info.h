#pragma once
// `amt dataset info`: a human-readable summary of a dataset file (DESIGN.md sections 4 and 7).
#include <ostream>
#include <string>

namespace amt {

/// Prints a summary of the dataset file at `path` to `out`: format, version, fps, units, up axis and
/// skeleton size; one line per character (vertices, faces, apparel share = % of vertices with mask
/// 1, split, rig bones) and per clip (character, motion, frames, ground-truth form, split); totals
/// of characters, clips and frames with their train / test split counts. Every character and clip
/// is checked as it is listed (DatasetReader::character_summary and clip_info); bad input throws
/// amt::Error.
void print_dataset_info(const std::string& path, std::ostream& out);

}  // namespace amt
