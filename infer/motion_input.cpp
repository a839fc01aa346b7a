#include "infer/motion_input.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "data_tools/builder/mmd_pose.h"
#include "data_tools/builder/pmx_dataset.h"
#include "data_tools/builder/pmx_physics.h"
#include "data_tools/formats/bvh_import.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/gltf_import.h"
#include "data_tools/formats/pmx_import.h"
#include "data_tools/formats/vmd_import.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/retarget.h"

namespace amt {

namespace {

std::string lower_extension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

// Adds the --motion-joint-map hint to a mapping error.
[[noreturn]] void rethrow_with_hint(const Error& e) {
  std::string message = e.what();
  if (message.find("could not match") != std::string::npos) message += " (for a motion: --motion-joint-map FILE)";
  throw Error(message);
}

// A canonical motion whose missing joints are placed (place_missing_joints) and mapping described.
void finish_canonical(CanonicalMotion&& canonical, const std::vector<std::string>& file_names, SourceMotion& out) {
  out.skeleton = std::move(canonical.skeleton);
  const std::vector<int> placed = place_missing_joints(out.skeleton.rest_joints, canonical.mapping);
  out.motion = std::move(canonical.motion);
  CanonicalRest rest;
  rest.mapping = canonical.mapping;
  rest.placed = placed;
  out.mapping = rest.describe(file_names);
}

// A VMD motion on the canonical skeleton of the PMX model it was made for: the model's bones posed frame by frame as
// MMD poses them (data_tools/builder/mmd_pose.h: IK, append rotations), brought to amt's frame, then each canonical
// joint turns with the global rotation of its mapped bone (PMX bones have no rest rotation, so that rotation is
// already relative to the rest pose) and the pelvis moves as its bone does, as to_canonical does for BVH and glTF.
void vmd_to_canonical(const MotionSpec& spec, const std::optional<JointMapFile>& user_map, SourceMotion& out) {
  const std::string& path = spec.spec;
  AMT_CHECK(!spec.model.empty(), path, ": motion: a VMD motion has no skeleton and needs the PMX model it was made ",
            "for: give it with --motion-model MODEL.pmx (or animate that .pmx as the --character)");
  AMT_CHECK(lower_extension(spec.model) == ".pmx", spec.model, ": --motion-model: expected the .pmx model the VMD ",
            "motion was made for, found extension '", lower_extension(spec.model), "'");
  const VmdMotion vmd = read_vmd(path);
  const PmxModel model = read_pmx(spec.model);
  AMT_CHECK(!model.bones.empty(), spec.model, ": bones: expected the bones a VMD motion poses, found none");
  const Skeleton file = pmx_skeleton(pmx_to_amt_frame(model, kPmxMetresPerUnit));
  CanonicalRest rest;
  try {
    rest = canonical_rest(file, user_map, spec.model);
  } catch (const Error& err) {
    rethrow_with_hint(err);
  }
  // Only the mapped bones' transforms are kept: a long dance on a model of hundreds of bones stays small.
  const int J = rest.skeleton.num_joints();
  const std::vector<int> mapped(rest.mapping.source_joint.begin(), rest.mapping.source_joint.begin() + J);
  const MmdBoneMotion bones = mmd_bone_motion(model, vmd, mapped);
  Motion& m = out.motion;
  m.fps = kVmdFps;
  m.joint_names = rest.skeleton.names;
  m.local_rotations.assign(size_t(bones.frames) * size_t(J), Eigen::Quaternionf::Identity());
  m.root_translation.setZero(bones.frames, 3);
  for (int t = 0; t < bones.frames; ++t) {
    // g[j]: canonical joint j's mapped bone, in amt's frame.
    const Transforms g = pmx_transforms_to_amt(Transforms(bones.globals.begin() + std::ptrdiff_t(size_t(t) * J),
                                                          bones.globals.begin() + std::ptrdiff_t(size_t(t + 1) * J)),
                                               kPmxMetresPerUnit);
    const auto global = [&](int j) -> Eigen::Matrix3f { return g[size_t(j)].leftCols<3>(); };
    for (int j = 0; j < J; ++j) {
      const int p = rest.skeleton.parents[size_t(j)];
      const Eigen::Matrix3f R = p >= 0 ? Eigen::Matrix3f(global(p).transpose() * global(j)) : global(j);
      m.rotation(t, j) = Eigen::Quaternionf(R).normalized();
    }
    m.root_translation.row(t) = g[0].col(3).transpose() - rest.skeleton.rest_joints.row(0);
  }
  out.skeleton = rest.skeleton;

  std::string notes = detail::concat("from a VMD motion on ", spec.model, ": ", vmd.bone_keys.size(),
                                     " bone keyframes on ", bones.matched_bones, " of the model's ", model.bones.size(),
                                     " bones, posed as MMD poses them (IK solved on every frame: the VMD's IK-enable "
                                     "track is not read)");
  if (bones.unmatched_keys > 0) {
    notes += detail::concat("\n  ", bones.unmatched_keys, " keyframes on bones the model does not have, ignored:");
    for (size_t k = 0; k < bones.unmatched_bones.size() && k < 12; ++k) notes += " " + bones.unmatched_bones[k];
    if (bones.unmatched_bones.size() > 12) notes += " ...";
  }
  if (!vmd.ignored_note().empty()) notes += "\n  " + vmd.ignored_note();
  out.mapping = notes + "\n  " + rest.describe(file.names);
}

}  // namespace

Motion motion_from_joint_transforms(const Skeleton& skeleton, const Transforms& transforms, float fps) {
  const int J = skeleton.num_joints();
  AMT_CHECK(J > 0 && transforms.size() % size_t(J) == 0, "joint transforms: expected a multiple of ", J,
            " transforms, found ", transforms.size());
  const int T = int(transforms.size() / size_t(J));
  Motion m;
  m.fps = fps;
  m.joint_names = skeleton.names;
  m.local_rotations.resize(size_t(T) * size_t(J));
  m.root_translation.resize(T, 3);
  for (int t = 0; t < T; ++t) {
    for (int j = 0; j < J; ++j) {
      const Transform34& X = transforms[size_t(t) * J + j];
      Eigen::Matrix3f R = X.leftCols<3>();
      const int p = skeleton.parents[size_t(j)];
      if (p >= 0) R = transforms[size_t(t) * J + p].leftCols<3>().transpose() * R;
      Eigen::Quaternionf q(R);
      m.rotation(t, j) = q.normalized();
    }
    m.root_translation.row(t) = transforms[size_t(t) * J].col(3).transpose() - skeleton.rest_joints.row(0);
  }
  return m;
}

SourceMotion load_motion(const MotionSpec& spec) {
  SourceMotion out;
  std::optional<JointMapFile> user_map;
  if (!spec.joint_map.empty()) user_map = read_joint_map(spec.joint_map);
  const std::string& path = spec.spec;

  if (const auto ds = split_dataset_spec(path)) {
    DatasetReader reader(ds->first);
    AMT_CHECK(reader.has_clip(ds->second), ds->first, ": /clips/", ds->second,
              ": expected a clip of the dataset, found none (it has ", reader.clip_names().size(), " clips",
              reader.clip_names().empty() ? "" : ", e.g. " + reader.clip_names()[0], ")");
    const ClipInfo info = reader.clip_info(ds->second);
    const CharacterData character = reader.read_character(info.character);
    AMT_CHECK(is_canonical(character.skeleton), ds->first, ": skeleton: expected the canonical 22 joints for a clip ",
              "the runtime plays, found ", character.skeleton.num_joints(), " joints");
    out.name = info.name;
    out.skeleton = character.skeleton;
    out.motion = motion_from_joint_transforms(character.skeleton,
                                              reader.read_joint_transforms(info.name, 0, info.num_frames), info.fps);
    out.dataset = ds->first;
    out.dataset_clip = info.name;
    out.dataset_character = info.character;
    return out;
  }
  AMT_CHECK(std::filesystem::exists(path), path, ": motion: expected a file, found none");
  out.name = std::filesystem::path(path).stem().string();
  const std::string e = lower_extension(path);
  if (e == ".bvh") {
    BvhImportOptions options;
    options.scale = spec.bvh_scale;
    options.fps = std::nullopt;
    options.joint_map = user_map;
    const BvhFile file = read_bvh(path);
    std::vector<std::string> names;
    for (const BvhJoint& j : file.joints) names.push_back(j.name);
    try {
      BvhImport imported = bvh_to_canonical(file, options);
      // The mapping names file joints by index into the converted skeleton (joints, then End Sites).
      const BvhMotion full = bvh_to_motion(file, imported.units.metres_per_unit);
      finish_canonical(std::move(imported.canonical), full.skeleton.names, out);
    } catch (const Error& err) {
      rethrow_with_hint(err);
    }
  } else if (e == ".glb" || e == ".gltf") {
    const GltfAsset asset = read_gltf(path);
    const GltfCharacter character = gltf_character(asset);
    const GltfMotion sampled = gltf_motion(asset, character, spec.clip, 30.0f);
    try {
      std::vector<int> parents(character.skeleton.parents.begin(), character.skeleton.parents.end());
      const JointMapping mapping = map_to_canonical(character.skeleton.names, parents, user_map, path);
      finish_canonical(to_canonical(character.skeleton, sampled.motion, mapping, path), character.skeleton.names, out);
    } catch (const Error& err) {
      rethrow_with_hint(err);
    }
    if (!sampled.clip.empty()) out.name = sampled.clip;
  } else if (e == ".vmd") {
    vmd_to_canonical(spec, user_map, out);
  } else {
    fail(path, ": motion: expected a .bvh, .glb, .gltf, .vmd file or file.h5:clip, found extension '", e, "'");
  }
  validate_motion(out.motion, out.skeleton, path);
  return out;
}

// === Playback

struct MotionPlayer::Impl {
  float fps = 30.0f;
  int frames = 0;
  // Exact dataset playback: the reader and clip; else the retargeted motion on the character.
  std::unique_ptr<DatasetReader> reader;
  std::string clip;
  int first = 0;
  Skeleton skeleton;
  Motion motion;
};

MotionPlayer::MotionPlayer(const SourceMotion& source, const RuntimeCharacter& character,
                           const PlaybackOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (options.fps) {
    AMT_CHECK(std::isfinite(*options.fps) && *options.fps > 0 && *options.fps <= 1000, "--fps: expected a frame rate ",
              "in (0, 1000], found ", *options.fps);
  }
  AMT_CHECK(options.frames >= 0, "--frames: expected a non-negative count, found ", options.frames);
  const bool same_character = !source.dataset.empty() && source.dataset == character.dataset &&
                              source.dataset_character == character.dataset_character;
  // File motions play at 30 fps unless told (docs/characters.md, "Conventions"); dataset clips at their own rate.
  std::optional<float> fps = options.fps;
  if (!fps && source.dataset.empty()) fps = 30.0f;
  const bool same_rate = !fps || std::abs(*fps - source.motion.fps) < 1e-4f;
  impl_->skeleton = character.skeleton;
  if (same_character && same_rate) {
    impl_->reader = std::make_unique<DatasetReader>(source.dataset);
    impl_->clip = source.dataset_clip;
    impl_->fps = source.motion.fps;
    impl_->frames = source.motion.num_frames();
  } else {
    Motion m = source.motion;
    if (!same_rate) m = resample_motion(m, *fps);
    impl_->motion = retarget_motion(m, source.skeleton, character.skeleton);
    impl_->fps = impl_->motion.fps;
    impl_->frames = impl_->motion.num_frames();
  }
  if (options.frames > 0) impl_->frames = std::min(impl_->frames, options.frames);
  AMT_CHECK(impl_->frames > 0, source.name, ": motion: expected at least one frame, found none");
}

MotionPlayer::~MotionPlayer() = default;
MotionPlayer::MotionPlayer(MotionPlayer&&) noexcept = default;
MotionPlayer& MotionPlayer::operator=(MotionPlayer&&) noexcept = default;

int MotionPlayer::num_frames() const {
  return impl_->frames;
}
float MotionPlayer::fps() const {
  return impl_->fps;
}
bool MotionPlayer::exact() const {
  return impl_->reader != nullptr;
}

Transforms MotionPlayer::frame(int t) const {
  AMT_CHECK(t >= 0 && t < impl_->frames, "motion: frame ", t, " out of range [0, ", impl_->frames, ")");
  if (impl_->reader) return impl_->reader->read_joint_transforms(impl_->clip, t, 1);
  return forward_kinematics(impl_->skeleton, impl_->motion, t);
}

}  // namespace amt
