#pragma once
// The `amt retarget-cloth` job (issue 13, item 3): the apparel motion of a source character carried onto a
// target character whose apparel has the same connectivity (data_tools/garment/cloth_retarget.h), under a target body
// motion, streamed to a GLB / OBJ sequence / dataset file like `amt animate` (infer/frame_writer.h).
//   source         a dataset clip "data.h5:clip" (its character's simulated apparel, body included), or a
//                  folder of OBJ frames frame_0000.obj, ... (whole meshes as `amt animate` writes them) with
//                  source_character giving their rest mesh and apparel mask
//   target         a dataset character "data.h5:character" (rest mesh, apparel mask, body weights)
//   target_motion  the target body's motion: a BVH, a glTF animation or a dataset clip, played on the target
//                  (infer/motion_input.h: retargeted unless it is a clip of the target itself); empty: the
//                  source clip's own motion retargeted onto the target
// The target body is skinned by its dataset body weights (paper eq. 4); its apparel rows are replaced by the
// retargeted apparel. Frame t of the target motion takes frame t of the source (at the source's frame rate).
#include <string>

#include "data_tools/garment/cloth_retarget.h"
#include "data_tools/geometry/metrics.h"
#include "infer/motion_input.h"

namespace amt {

/// Everything `amt retarget-cloth` takes.
struct RetargetClothOptions {
  std::string source;
  std::string source_character;
  std::string target;
  MotionSpec target_motion;
  std::string out;
  /// At most this many frames (0: all of the target motion).
  int frames = 0;
  /// Frame rate of an OBJ source (a dataset clip has its own).
  float fps = 30.0f;
  ClothRetargetOptions retarget;
  /// Print the inputs and a progress line on stderr.
  bool verbose = true;
};

/// What a run did.
struct RetargetClothSummary {
  std::string output;
  int frames = 0, apparel_vertices = 0;
  float fps = 30.0f;
  double registration_seconds = 0, total_seconds = 0;
  /// Retargeting time per frame (steps 3-6 and the collision passes, no reading or writing): median, p95.
  double frame_median = 0, frame_p95 = 0;
  /// Target apparel vertices inside the target body, summed over frames, before and after resolution.
  Penetration before, after;
  int64_t shortened = 0;
};

/// Runs the job. Throws amt::Error on bad input before the output is created where it can be checked up
/// front: unreadable inputs, different apparel connectivity (naming both files), a source with fewer frames
/// than the target motion or a missing OBJ frame (naming it). The output is complete or absent.
RetargetClothSummary retarget_cloth(const RetargetClothOptions& options);

/// The summary as a few lines of text.
std::string describe(const RetargetClothSummary& summary);

}  // namespace amt
