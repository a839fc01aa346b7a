#include "data_tools/builder/motion_library.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "data_tools/formats/bvh_import.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/retarget.h"

namespace amt {

namespace fs = std::filesystem;

// === Options

void validate_motion_library_options(const MotionLibraryOptions& o) {
  AMT_CHECK(o.clip_frames >= 2 && o.clip_frames <= 100000, "motions: --frames: expected frames per clip in [2, 100000], found ",
            o.clip_frames);
  AMT_CHECK(o.procedural >= 0 && o.procedural <= 100000,
            "motions: --procedural: expected a number of procedural motions in [0, 100000], found ", o.procedural);
  AMT_CHECK(std::isfinite(o.fps) && o.fps > 0 && o.fps <= 1000, "motions: fps: expected (0, 1000], found ", o.fps);
  AMT_CHECK(o.min_tail_frames >= 2, "motions: min_tail_frames: expected >= 2, found ", o.min_tail_frames);
}

uint64_t derive_seed(uint64_t seed, uint64_t stream) {
  // SplitMix64 (Steele, Lea and Flood 2014) over the seed, then over the mixed seed plus the stream.
  auto mix = [](uint64_t z) {
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  };
  return mix(mix(seed) + stream);
}

// === Clips

std::vector<std::string> list_bvh_files(const std::string& folder) {
  std::error_code error;
  AMT_CHECK(fs::is_directory(folder, error), folder, ": --motions: no such folder (expected a folder of .bvh files)");
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(folder, error)) {
    std::string extension = entry.path().extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
    if (extension == ".bvh" && !entry.is_directory()) files.push_back(entry.path().string());
  }
  AMT_CHECK(!error, folder, ": --motions: cannot list the folder: ", error.message());
  AMT_CHECK(!files.empty(), folder, ": --motions: the folder has no .bvh file (expected at least one)");
  std::sort(files.begin(), files.end());
  return files;
}

std::vector<std::pair<int, int>> clip_windows(int motion_frames, int clip_frames, int min_tail_frames) {
  std::vector<std::pair<int, int>> windows;
  int first = 0;
  for (; first + clip_frames <= motion_frames; first += clip_frames) windows.emplace_back(first, clip_frames);
  const int tail = motion_frames - first;
  if (tail >= min_tail_frames || (windows.empty() && tail >= 2)) windows.emplace_back(first, tail);
  return windows;
}

Motion cut_window(const Motion& motion, int first_frame, int frames) {
  AMT_CHECK(frames >= 1 && first_frame >= 0 && first_frame + frames <= motion.num_frames() && motion.num_joints() >= 1,
            "cut_window: expected a window within the motion's ", motion.num_frames(), " frames, found frames ",
            first_frame, " to ", first_frame + frames - 1);
  const int J = motion.num_joints();
  // Heading of the root at the first frame: its forward axis (+Z) on the floor, or its side axis (+X).
  const Eigen::Quaternionf q0 = motion.rotation(first_frame, 0);
  const Eigen::Vector3f forward = q0 * Eigen::Vector3f::UnitZ();
  float heading = 0.0f;  // rotation about +Y that takes +Z to the root's heading
  if (std::hypot(forward.x(), forward.z()) > 0.1f) {
    heading = std::atan2(forward.x(), forward.z());
  } else {
    const Eigen::Vector3f side = q0 * Eigen::Vector3f::UnitX();
    heading = std::atan2(-side.z(), side.x());
  }
  const Eigen::Quaternionf turn(Eigen::AngleAxisf(-heading, Eigen::Vector3f::UnitY()));
  const Eigen::Vector3f start = motion.root_translation.row(first_frame).transpose();

  Motion window;
  window.fps = motion.fps;
  window.joint_names = motion.joint_names;
  window.local_rotations.resize(static_cast<size_t>(frames) * J);
  window.root_translation.resize(frames, 3);
  for (int t = 0; t < frames; ++t) {
    for (int j = 0; j < J; ++j) window.rotation(t, j) = motion.rotation(first_frame + t, j);
    window.rotation(t, 0) = (turn * window.rotation(t, 0)).normalized();
    const Eigen::Vector3f offset = motion.root_translation.row(first_frame + t).transpose() - start;
    Eigen::Vector3f root = turn * offset;
    root.y() = motion.root_translation(first_frame + t, 1);
    window.root_translation.row(t) = root.transpose();
  }
  return window;
}

Motion blend_from_rest(const Motion& motion, float blend_seconds) {
  AMT_CHECK(std::isfinite(blend_seconds) && blend_seconds >= 0 && blend_seconds <= 60,
            "blend_from_rest: expected blend seconds in [0, 60], found ", blend_seconds);
  Motion out = motion;
  const int T = motion.num_frames(), J = motion.num_joints();
  if (T == 0) return out;
  const int b = std::min(static_cast<int>(std::lround(blend_seconds * motion.fps)), T - 1);
  const Eigen::Quaternionf identity = Eigen::Quaternionf::Identity();
  // Frame 0 is set exactly (slerp with weight 0 is the identity only to rounding).
  for (int j = 0; j < J; ++j) out.rotation(0, j) = identity;
  out.root_translation.row(0).setZero();
  // Per joint, the rotations are put on one continuous quaternion branch (q(0).w >= 0, then each q(t) on the side
  // of q(t-1)) and interpolated from the identity along that branch: exp(w log q). Eigen's slerp would take the
  // shortest arc to each frame separately, which flips direction when a joint's rotation from rest passes 180
  // degrees (a dancer's turn) and makes the body jump between two frames.
  for (int j = 0; j < J; ++j) {
    Eigen::Quaternionf previous = motion.rotation(0, j);
    if (previous.w() < 0) previous.coeffs() *= -1.0f;
    for (int t = 1; t < b; ++t) {
      Eigen::Quaternionf q = motion.rotation(t, j);
      if (q.coeffs().dot(previous.coeffs()) < 0) q.coeffs() *= -1.0f;
      previous = q;
      const float s = static_cast<float>(t) / b;
      const float w = s * s * (3.0f - 2.0f * s);
      const float sine = q.vec().norm();
      const float half_angle = std::atan2(sine, q.w());  // in [0, pi]: rotation angle up to 360 degrees
      Eigen::Quaternionf blended = identity;
      if (sine > 1e-12f) {
        blended.w() = std::cos(w * half_angle);
        blended.vec() = q.vec() / sine * std::sin(w * half_angle);
      }
      out.rotation(t, j) = blended.normalized();
    }
  }
  for (int t = 1; t < b; ++t) {
    const float s = static_cast<float>(t) / b;
    const float w = s * s * (3.0f - 2.0f * s);
    out.root_translation.row(t) = w * motion.root_translation.row(t);
  }
  return out;
}

Motion clip_on_character(const MotionClip& clip, const Skeleton& character, float blend_seconds) {
  static const Skeleton canonical = canonical_skeleton();
  return blend_from_rest(retarget_motion(clip.motion, canonical, character), blend_seconds);
}

Motion canonical_bvh_motion(const std::string& path, float fps) {
  BvhImportOptions options;
  options.fps = fps;
  const BvhImport imported = import_bvh(path, options);
  return retarget_motion(imported.canonical.motion, imported.canonical.skeleton, canonical_skeleton());
}

std::vector<MotionClip> build_motion_library(const MotionLibraryOptions& options) {
  validate_motion_library_options(options);
  std::vector<MotionClip> clips;
  auto add_windows = [&](const Motion& motion, const std::string& prefix, const std::string& source) {
    int k = 0;
    for (const auto& [first, frames] : clip_windows(motion.num_frames(), options.clip_frames, options.min_tail_frames)) {
      char suffix[16];
      std::snprintf(suffix, sizeof(suffix), "-%03d", k++);
      clips.push_back({prefix + suffix, source, first, cut_window(motion, first, frames)});
    }
  };
  if (!options.bvh_folder.empty()) {
    for (const std::string& path : list_bvh_files(options.bvh_folder)) {
      const Motion motion = canonical_bvh_motion(path, options.fps);
      add_windows(motion, "bvh-" + fs::path(path).stem().string(), fs::path(path).filename().string());
    }
  }
  for (int i = 0; i < options.procedural; ++i) {
    const auto kind = static_cast<ProceduralKind>(i % kProceduralKindCount);
    const Motion motion = random_procedural_motion(kind, derive_seed(options.seed, static_cast<uint64_t>(i)),
                                                   options.clip_frames, options.fps);
    char name[64];
    std::snprintf(name, sizeof(name), "proc-%s-%03d", procedural_kind_name(kind), i);
    clips.push_back({name, "procedural", 0, cut_window(motion, 0, motion.num_frames())});
  }
  AMT_CHECK(!clips.empty(), "motions: no clip (expected a --motions folder with BVH files or --procedural > 0)");
  return clips;
}

}  // namespace amt
