#include "data_tools/builder/garment_pairs.h"

#include <chrono>
#include <cstdio>
#include <exception>
#include <map>
#include <memory>
#include <ostream>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/builder/body_generator.h"
#include "data_tools/garment/cloth_retarget.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/builder/motion_library.h"
#include "data_tools/geometry/skeleton.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace amt {
namespace {

// Streams of derive_seed(options.build.seed, .), apart from the dataset builder's.
constexpr uint64_t kPairBodyStream = 0x70626f6479ULL;     // the two bodies of each pair
constexpr uint64_t kPairApparelStream = 0x70617070ULL;    // the garment of each pair
constexpr uint64_t kPairMotionStream = 0x706d6f74ULL;     // procedural motions

std::string pair_name(int p, char side) {
  char text[32];
  std::snprintf(text, sizeof(text), "pair-%02d-%c", p, side);
  return text;
}

}  // namespace

GarmentPairReport build_garment_pairs(const GarmentPairOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const DatasetBuildOptions& o = options.build;
  validate_build_options(o);
  AMT_CHECK(options.pairs >= 1 && options.pairs <= 100, "--pairs: expected 1 to 100 pairs, found ", options.pairs);
  // Before minutes of simulation: the output can be replaced and its folder made.
  check_replaceable_file(o.out);
  create_parent_folder(o.out);
  const std::vector<MotionClip> clips = motion_library_of(o, derive_seed(o.seed, kPairMotionStream));
  AMT_CHECK(!clips.empty(), o.out, ": expected at least one motion clip (--procedural or --motions), found none");

  // The characters: per pair the first body dressed with the pair's garment, the second body dressed with the
  // same seed, options and the first one's topology.
  std::vector<DressedCharacter> dressed;
  std::vector<std::string> names;
  for (int p = 0; p < options.pairs; ++p) {
    const uint64_t garment = derive_seed(derive_seed(o.seed, kPairApparelStream), uint64_t(p));
    for (int side = 0; side < 2; ++side) {
      const uint64_t body_seed = derive_seed(derive_seed(o.seed, kPairBodyStream), uint64_t(2 * p + side));
      const GeneratedBody body = generate_body(sample_body_params(body_seed), o.vertices);
      ApparelOptions apparel = o.apparel;
      if (side == 1) apparel.topology = dressed.back().topology;
      dressed.push_back(dress_character(body, garment, apparel));
      names.push_back(pair_name(p, side == 0 ? 'a' : 'b'));
      if (o.progress) *o.progress << "pairs: dressed " << names.back() << "\n";
    }
  }

  // Every (character, clip) simulated in parallel, one simulator per thread and character.
  const int C = int(dressed.size()), M = int(clips.size());
  struct Job {
    Transforms joints, rig;
    int frames = 0;
  };
  std::vector<Job> jobs(size_t(C * M));
  for (int c = 0; c < C; ++c) {
    for (int k = 0; k < M; ++k) {
      const Motion motion = clip_on_character(clips[size_t(k)], dressed[size_t(c)].body.skeleton, o.blend_seconds);
      jobs[size_t(c * M + k)].frames = motion.num_frames();
      jobs[size_t(c * M + k)].joints = forward_kinematics(dressed[size_t(c)].body.skeleton, motion);
    }
  }
  std::exception_ptr failure;
#pragma omp parallel for schedule(dynamic, 1)
  for (int j = 0; j < C * M; ++j) {
    try {
      std::unique_ptr<ApparelSimulator> simulator;
      Job& job = jobs[size_t(j)];
      job.rig = simulate_clip(dressed[size_t(j / M)], job.joints, job.frames, o, simulator);
    } catch (...) {
#pragma omp critical(amt_garment_pairs_failure)
      if (!failure) failure = std::current_exception();
    }
  }
  if (failure) std::rethrow_exception(failure);

  GarmentPairReport report;
  DatasetWriter writer(o.out, o.fps, canonical_joint_names());
  for (int c = 0; c < C; ++c) writer.add_character(dressed[size_t(c)].character_data(names[size_t(c)], "test"));
  const int J = kCanonicalJointCount;
  for (int c = 0; c < C; ++c) {
    const int B = dressed[size_t(c)].rig.num_bones();
    for (int k = 0; k < M; ++k) {
      const Job& job = jobs[size_t(c * M + k)];
      ClipInfo info;
      info.name = names[size_t(c)] + "__" + clips[size_t(k)].name;
      info.character = names[size_t(c)];
      info.motion = clips[size_t(k)].name;
      info.split = "test";
      info.fps = o.fps;
      info.ground_truth = GroundTruth::kRig;
      writer.begin_clip(info);
      for (int t = 0; t < job.frames; ++t) {
        writer.append_frame(Transforms(job.joints.begin() + ptrdiff_t(t) * J, job.joints.begin() + ptrdiff_t(t + 1) * J),
                            Transforms(job.rig.begin() + ptrdiff_t(t) * B, job.rig.begin() + ptrdiff_t(t + 1) * B));
      }
      writer.end_clip();
      ++report.clips;
      report.frames += job.frames;
    }
  }
  writer.commit();
  report.characters = C;
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

std::vector<GarmentPair> find_garment_pairs(const DatasetReader& reader) {
  const std::vector<std::string>& characters = reader.character_names();
  // Candidates by apparel vertex count (cheap), then the full connectivity check.
  std::map<std::string, int> apparel;
  for (const std::string& c : characters) apparel[c] = reader.character_summary(c).num_apparel_vertices;
  std::map<std::string, ClothCharacter> loaded;
  auto load = [&](const std::string& name) -> const ClothCharacter& {
    auto it = loaded.find(name);
    if (it == loaded.end()) {
      CharacterData data = reader.read_character(name);
      ClothCharacter c{reader.path() + ":" + name, std::move(data.mesh), std::move(data.apparel_mask)};
      it = loaded.emplace(name, std::move(c)).first;
    }
    return it->second;
  };
  // Clips by character and motion.
  std::map<std::string, std::map<std::string, ClipInfo>> clips;
  for (const std::string& name : reader.clip_names()) {
    const ClipInfo info = reader.clip_info(name);
    clips[info.character][info.motion] = info;
  }
  std::vector<GarmentPair> pairs;
  for (const std::string& a : characters) {
    for (const std::string& b : characters) {
      if (a == b || apparel[a] == 0 || apparel[a] != apparel[b] || !clips.count(a) || !clips.count(b)) continue;
      try {
        check_same_apparel_connectivity(load(a), load(b));
      } catch (const Error&) {
        continue;
      }
      for (const auto& [motion, source] : clips[a]) {
        const auto it = clips[b].find(motion);
        if (it == clips[b].end() || it->second.num_frames != source.num_frames) continue;
        pairs.push_back({a, b, source.name, it->second.name});
      }
    }
  }
  return pairs;
}

}  // namespace amt
