#pragma once
// A micro dataset for the training tests: a capsule character on the canonical skeleton (a few
// hundred vertices) whose pelvis capsules are "apparel" that trails the body by two frames, and
// procedural walks. Small enough that every module trains for dozens of steps in a second.
#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/builder/example_dataset.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/threads.h"
#include "tests/test_support.h"

namespace amt::test {

/// Options of the micro dataset.
struct MicroDatasetOptions {
  int vertices = 300;
  int frames = 30;
  int clips = 2;
  /// Joint names written to the file (empty: the canonical ones); changes nothing else.
  std::vector<std::string> joint_names;
};

/// Writes the micro dataset to `path`: character "capsules" (train), clips "walk0", "walk1", ...
/// (train) at different speeds. Apparel ground truth is the rigid skinning of frame max(t - 2, 0).
inline void write_micro_dataset(const std::string& path, const MicroDatasetOptions& options = {}) {
  Skeleton skeleton = canonical_skeleton();
  if (!options.joint_names.empty()) skeleton.names = options.joint_names;
  CharacterData character = capsule_example_character(skeleton, options.vertices);
  const int N = character.mesh.num_vertices();
  for (int i = 0; i < N; ++i) {  // the pelvis capsules (bound to the pelvis) become apparel
    character.apparel_mask[i] = character.body_weights(i, kPelvis) == 1.0f ? 1 : 0;
  }
  DatasetWriter writer(path, 30.0f, skeleton.names);
  writer.add_character(character);
  const SparseWeights weights = sparsify_weights(character.body_weights);
  for (int c = 0; c < options.clips; ++c) {
    Motion walk = walk_motion(options.frames, 30.0f, 1.0f + 0.4f * c);
    walk.joint_names = skeleton.names;
    ClipInfo clip;
    clip.name = "walk" + std::to_string(c);
    clip.character = character.name;
    clip.motion = "procedural_walk";
    clip.split = "train";
    writer.begin_clip(clip);
    std::vector<MatrixX3f> posed(options.frames);
    for (int t = 0; t < options.frames; ++t) {
      const Transforms joints = forward_kinematics(skeleton, walk, t);
      linear_blend_skinning(character.mesh.V, weights, skinning_matrices(skeleton, joints), posed[t]);
      MatrixX3f gt = posed[t];
      const MatrixX3f& lagged = posed[std::max(t - 2, 0)];
      for (int i = 0; i < N; ++i) {
        if (character.apparel_mask[i]) gt.row(i) = lagged.row(i);
      }
      writer.append_frame(joints, gt);
    }
    writer.end_clip();
  }
  writer.commit();
}

/// A fresh folder for this test process, removed when the process exits (tests/test_support.h).
inline std::string test_directory(const std::string& name) { return temp_dir(name).string(); }

/// One thread for tiny tensors: extra threads only add synchronisation (and make timings noisy).
inline void use_one_thread() { set_thread_count(1); }

}  // namespace amt::test
