#include "data_tools/builder/example_dataset.h"

#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/shapes.h"

namespace amt {

CharacterData capsule_example_character(const Skeleton& skeleton, int vertices) {
  CharacterData character;
  character.name = "capsules";
  character.skeleton = skeleton;
  character.split = "train";
  std::vector<int32_t> joint_of_vertex;
  character.mesh = capsule_character(skeleton.rest_joints, skeleton.parents, vertices, &joint_of_vertex);
  const int N = character.mesh.num_vertices();
  character.apparel_mask.assign(N, 0);
  character.body_weights = MatrixXfR::Zero(N, skeleton.num_joints());
  for (int i = 0; i < N; ++i) character.body_weights(i, joint_of_vertex[i]) = 1.0f;
  return character;
}

void write_example_dataset(const std::string& path, const ExampleDatasetOptions& options) {
  AMT_CHECK(options.vertices >= 100 && options.frames >= 1, "dataset example: expected --vertices >= 100 and --frames "
            ">= 1, found ", options.vertices, " and ", options.frames);
  const Skeleton skeleton = canonical_skeleton();
  const CharacterData character = capsule_example_character(skeleton, options.vertices);

  const Motion walk = walk_motion(options.frames, options.fps);
  DatasetWriter writer(path, options.fps, skeleton.names);
  writer.add_character(character);
  ClipInfo clip;
  clip.name = "capsules_walk";
  clip.character = character.name;
  clip.motion = "procedural_walk";
  clip.split = "train";
  clip.fps = options.fps;
  writer.begin_clip(clip);
  const SparseWeights weights = sparsify_weights(character.body_weights);
  MatrixX3f posed;
  for (int t = 0; t < walk.num_frames(); ++t) {
    const Transforms joints = forward_kinematics(skeleton, walk, t);
    linear_blend_skinning(character.mesh.V, weights, skinning_matrices(skeleton, joints), posed);
    writer.append_frame(joints, posed);
  }
  writer.end_clip();
  writer.commit();
}

}  // namespace amt
