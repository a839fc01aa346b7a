#include "infer/retarget_cloth.h"

#include "data_tools/formats/atomic_file.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/obj_io.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"
#include "infer/character_input.h"
#include "infer/frame_writer.h"

namespace amt {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// "data.h5:name" -> (file, name); anything else is an error naming the option.
std::pair<std::string, std::string> dataset_spec(const std::string& spec, const char* option, const char* what) {
  const auto split = split_dataset_spec(spec);
  AMT_CHECK(split.has_value(), option, ": expected ", what, " as data.h5:name, found '", spec, "'");
  return *split;
}

// A dataset character as one side of the retargeting.
struct DatasetCharacter {
  std::string spec;
  CharacterData data;
};

DatasetCharacter read_dataset_character(const std::string& spec, const char* option) {
  const auto [file, name] = dataset_spec(spec, option, "a dataset character");
  const DatasetReader reader(file);
  AMT_CHECK(reader.has_character(name), spec, ": ", option, ": no character '", name, "' in ", file);
  return {spec, reader.read_character(name)};
}

// The source's frames: a dataset clip read frame by frame, or a folder of OBJ files.
class SourceFrames {
 public:
  SourceFrames(const RetargetClothOptions& o, DatasetCharacter& character) {
    if (const auto split = split_dataset_spec(o.source)) {
      reader_.emplace(split->first);
      clip_ = split->second;
      AMT_CHECK(reader_->has_clip(clip_), o.source, ": --source: no clip '", clip_, "' in ", split->first);
      const ClipInfo info = reader_->clip_info(clip_);
      frames_ = info.num_frames;
      fps_ = info.fps;
      AMT_CHECK(o.source_character.empty() || o.source_character == split->first + ":" + info.character, o.source,
                ": --source-character: a dataset clip brings its own character (", info.character, "), found '",
                o.source_character, "'");
      character = {split->first + ":" + info.character, reader_->read_character(info.character)};
      return;
    }
    AMT_CHECK(std::filesystem::is_directory(o.source), o.source,
              ": --source: expected a dataset clip data.h5:clip or a folder of OBJ frames (frame_0000.obj, ...)");
    AMT_CHECK(!o.source_character.empty(), o.source,
              ": --source-character: an OBJ sequence needs its rest character (data.h5:character)");
    character = read_dataset_character(o.source_character, "--source-character");
    folder_ = o.source;
    fps_ = o.fps;
    // The frames are frame_<t>.obj for t = 0, 1, ...: every one up to the last must be there.
    std::set<int> found;
    for (const auto& entry : std::filesystem::directory_iterator(folder_)) {
      const std::string name = entry.path().filename().string();
      int t = -1;
      char tail = 0;
      if (std::sscanf(name.c_str(), "frame_%d.ob%c", &t, &tail) == 2 && tail == 'j' && t >= 0 &&
          name == std::filesystem::path(obj_path(t)).filename().string())
        found.insert(t);
    }
    AMT_CHECK(!found.empty(), folder_,
              ": --source: expected the OBJ frames frame_0000.obj, frame_0001.obj, ..., found none");
    frames_ = *found.rbegin() + 1;
    for (int t = 0; t < frames_; ++t)
      AMT_CHECK(found.count(t), obj_path(t), ": --source: missing OBJ frame ", t, " (found ", found.size(),
                " frames up to ", std::filesystem::path(obj_path(frames_ - 1)).filename().string(), ")");
    vertices_ = character.data.mesh.num_vertices();
  }

  int num_frames() const { return frames_; }
  float fps() const { return fps_; }
  std::string describe() const { return reader_ ? reader_->path() + ":" + clip_ : folder_; }

  MatrixX3f frame(int t) const {
    if (reader_) return reader_->read_vertices(clip_, t, 1);
    const std::string path = obj_path(t);
    TriMesh mesh = read_obj(path);
    AMT_CHECK(mesh.num_vertices() == vertices_, path, ": vertices: expected ", vertices_,
              " (as the source character), found ", mesh.num_vertices());
    return std::move(mesh.V);
  }

 private:
  std::string obj_path(int t) const {
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%04d.obj", t);
    return (std::filesystem::path(folder_) / name).string();
  }

  std::optional<DatasetReader> reader_;
  std::string clip_, folder_;
  int frames_ = 0, vertices_ = 0;
  float fps_ = 30.0f;
};

}  // namespace

RetargetClothSummary retarget_cloth(const RetargetClothOptions& o) {
  const auto job_start = Clock::now();
  RetargetClothSummary s;
  output_kind(o.out);  // rejects .gltf / .obj names before any work
  check_output_not_input(o.out, "--out",
                         {{o.source, "--source"},
                          {o.source_character, "--source-character"},
                          {o.target, "--target"},
                          {o.target_motion.spec, "--target-motion"},
                          {o.target_motion.joint_map, "--motion-joint-map"}});

  DatasetCharacter source_character;
  const SourceFrames source(o, source_character);
  const DatasetCharacter target = read_dataset_character(o.target, "--target");
  const ClothCharacter source_side{source_character.spec, source_character.data.mesh,
                                   source_character.data.apparel_mask};
  const ClothCharacter target_side{target.spec, target.data.mesh, target.data.apparel_mask};
  ClothRetargeter retargeter(source_side, target_side, o.retarget);
  s.registration_seconds = retargeter.registration_seconds();
  s.apparel_vertices = retargeter.num_apparel();

  // The target body's motion, at the source's frame rate.
  MotionSpec motion_spec = o.target_motion;
  if (motion_spec.spec.empty()) {
    AMT_CHECK(split_dataset_spec(o.source).has_value(), o.source,
              ": --target-motion: an OBJ source has no motion of its own; expected a BVH, glTF or data.h5:clip");
    motion_spec.spec = o.source;
  }
  const SourceMotion motion = load_motion(motion_spec);
  const RuntimeCharacter target_runtime = load_character(CharacterSpec{o.target, "", ""});
  PlaybackOptions playback;
  playback.fps = source.fps();
  playback.frames = o.frames;
  const MotionPlayer player(motion, target_runtime, playback);
  s.frames = player.num_frames();
  s.fps = player.fps();
  AMT_CHECK(source.num_frames() >= s.frames, source.describe(), ": --source: has ", source.num_frames(),
            " frames, the target motion ", motion_spec.spec, " ", s.frames, ": expected at least ", s.frames,
            " (--frames ", source.num_frames(), " retargets the first ", source.num_frames(), ")");
  if (o.verbose) {
    std::cerr << "retarget-cloth: source " << source.describe() << " (" << source.num_frames() << " frames), character "
              << source_character.spec << "\n"
              << "retarget-cloth: target " << target.spec << ", motion " << motion.name << " ("
              << (player.exact() ? "dataset transforms as stored" : "retargeted onto the target") << ")\n"
              << "retarget-cloth: " << s.apparel_vertices << " apparel vertices registered in "
              << 1e3 * s.registration_seconds << " ms\n";
  }

  check_output_writable(o.out);
  OutputInfo info;
  info.character = target.data.name;
  info.mesh = target.data.mesh;
  info.skeleton = target.data.skeleton;
  info.apparel_mask = target.data.apparel_mask;
  info.weights = target.data.body_weights;
  info.clip = target.data.name + "__" + motion.name;
  info.motion = motion.name;
  info.frames = s.frames;
  info.fps = s.fps;
  info.made_by = "amt retarget-cloth";
  std::unique_ptr<FrameWriter> writer = open_frame_writer(o.out, info);

  std::vector<float> frame_seconds;
  MatrixX3f V;
  auto last_print = Clock::now();
  const auto loop_start = Clock::now();
  for (int t = 0; t < s.frames; ++t) {
    const Transforms T = player.frame(t);
    linear_blend_skinning(target.data.mesh.V, target.data.body_weights, skinning_matrices(target.data.skeleton, T), V);
    const MatrixX3f source_frame = source.frame(t);
    const auto start = Clock::now();
    const ClothRetargetReport report = retargeter.retarget(source_frame, V);
    frame_seconds.push_back(float(seconds_since(start)));
    writer->append(V, T);
    s.before.inside += report.before.inside, s.before.total += report.before.total;
    s.before.depth_sum_cm += report.before.depth_sum_cm;
    s.after.inside += report.after.inside, s.after.total += report.after.total;
    s.after.depth_sum_cm += report.after.depth_sum_cm;
    s.shortened += report.shortened;
    if (o.verbose && (seconds_since(last_print) > 1.0 || t + 1 == s.frames)) {
      last_print = Clock::now();
      const double rate = (t + 1) / std::max(seconds_since(loop_start), 1e-9);
      std::fprintf(stderr, "\rretarget-cloth: %d/%d frames, %.1f frames/s   ", t + 1, s.frames, rate);
      if (t + 1 == s.frames) std::fprintf(stderr, "\n");
    }
  }
  s.output = writer->finish();
  std::sort(frame_seconds.begin(), frame_seconds.end());
  if (!frame_seconds.empty()) {
    s.frame_median = frame_seconds[frame_seconds.size() / 2];
    s.frame_p95 = frame_seconds[std::min(frame_seconds.size() - 1, size_t(std::ceil(0.95 * frame_seconds.size())) - 1)];
  }
  s.total_seconds = seconds_since(job_start);
  return s;
}

std::string describe(const RetargetClothSummary& s) {
  std::ostringstream out;
  char line[256];
  out << "wrote " << s.output << "\n";
  std::snprintf(line, sizeof(line), "frames: %d at %.4g fps, %d apparel vertices (registration %.1f ms)\n", s.frames,
                s.fps, s.apparel_vertices, 1e3 * s.registration_seconds);
  out << line;
  std::snprintf(line, sizeof(line), "retargeting per frame: median %.2f ms, p95 %.2f ms\n", 1e3 * s.frame_median,
                1e3 * s.frame_p95);
  out << line;
  std::snprintf(line, sizeof(line),
                "penetration share: %.2f %% of apparel vertices before resolution, %.2f %% after (mean depth %.2f cm "
                "before); %.2f %% of detail vectors shortened\n",
                100.0 * s.before.share(), 100.0 * s.after.share(), s.before.mean_depth_cm(),
                s.before.total > 0 ? 100.0 * double(s.shortened) / double(s.before.total) : 0.0);
  out << line;
  std::snprintf(line, sizeof(line), "total: %.1f s\n", s.total_seconds);
  out << line;
  return out.str();
}

}  // namespace amt
