#pragma once
// Garment pair sets (issue 13, item 4): the test bed of cloth retargeting. Each pair is two generated bodies
// dressed with one garment template: the same apparel seed and options, and the apparel topology of the first
// body (data_tools/builder/apparel.h ApparelTopology), so the two apparel meshes have identical connectivity and
// differ only in positions (the pieces laid out relative to each body). Both are simulated under the same
// motion clips with the dataset builder's settings (data_tools/builder/dataset_builder.h simulate_clip), so the
// apparel motion of body A retargeted onto body B can be scored against B's own simulation.
//
// Output: one dataset file (data_tools/formats/dataset_file.h) with characters "pair-00-a", "pair-00-b", ... (split
// "test": no model has trained on them) and clips "<character>__<motion>", ground truth as rig_transforms.
// Pairs are found again by find_garment_pairs: characters of a file whose apparel has the same connectivity
// and that have clips of the same motion.
#include <iosfwd>
#include <string>
#include <vector>

#include "data_tools/builder/dataset_builder.h"
#include "data_tools/formats/dataset_file.h"

namespace amt {

/// What build_garment_pairs makes.
///   build   the dataset builder's settings (seed, vertices, frames, procedural clips or a BVH folder,
///           physics, apparel); build.out is the output .h5 file; characters, splits and shards are unused
///   pairs   number of body pairs (>= 1)
struct GarmentPairOptions {
  DatasetBuildOptions build;
  int pairs = 4;
};

/// Figures of a run: characters and clips written, frames simulated, seconds.
struct GarmentPairReport {
  int characters = 0, clips = 0;
  int64_t frames = 0;
  double seconds = 0;
};

/// Builds the pair set into options.build.out (written to a temporary name, then renamed). Throws amt::Error
/// on invalid options (validate_build_options) or pairs < 1.
GarmentPairReport build_garment_pairs(const GarmentPairOptions& options);

/// A source and a target clip of the same motion on two characters with the same apparel connectivity.
struct GarmentPair {
  std::string source_character, target_character;
  std::string source_clip, target_clip;
};

/// Every ordered pair (A -> B and B -> A) of the file: characters with the same apparel connectivity
/// (check_same_apparel_connectivity, data_tools/garment/cloth_retarget.h) and a clip of the same motion with the same
/// frame count, in file order.
std::vector<GarmentPair> find_garment_pairs(const DatasetReader& reader);

}  // namespace amt
