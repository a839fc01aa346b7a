#include "data_tools/builder/artist_style_dataset.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/error.h"

namespace amt {

ArtistStyleDatasetSummary write_artist_style_dataset(const std::string& in, const std::string& out,
                                                     const ArtistStyleDatasetOptions& options) {
  namespace fs = std::filesystem;
  std::error_code error;
  AMT_CHECK(fs::is_regular_file(in, error), in, ": no such dataset file (expected a shard written by amt)");
  AMT_CHECK(!fs::exists(out, error) || !fs::equivalent(in, out, error), out,
            ": the output is the input shard; expected another path");
  AMT_CHECK(options.max_clips >= 0, "artist style: max_clips: expected at least 0, found ", options.max_clips);
  const DatasetReader reader(in);
  std::vector<std::string> characters = reader.character_names();
  if (!options.character.empty()) {
    AMT_CHECK(reader.has_character(options.character), in, ": /characters/", options.character,
              ": no such character (expected one of the file's ", characters.size(), ")");
    characters = {options.character};
  }
  // The clips of each character, in file order, at most max_clips each.
  std::vector<std::vector<ClipInfo>> clips(characters.size());
  int total = 0;
  for (const std::string& clip : reader.clip_names()) {
    const ClipInfo info = reader.clip_info(clip);
    const auto at = std::find(characters.begin(), characters.end(), info.character);
    if (at == characters.end()) continue;
    auto& list = clips[size_t(at - characters.begin())];
    if (options.max_clips > 0 && int(list.size()) >= options.max_clips) continue;
    list.push_back(info);
    ++total;
  }

  DatasetWriter writer(out, reader.fps(), reader.joint_names());
  ArtistStyleDatasetSummary summary;
  const auto start = std::chrono::steady_clock::now();
  for (size_t c = 0; c < characters.size(); ++c) {
    ArtistStyleCharacter remake;
    try {
      remake = artist_style_character(reader.read_character(characters[c]), options.remake);
    } catch (const Error& e) {
      throw Error(in + ": /characters/" + characters[c] + ": artist style: " + e.what());
    }
    remake.character.name = characters[c];
    writer.add_character(remake.character);
    ++summary.characters;
    summary.vertices += remake.character.mesh.num_vertices();
    for (ClipInfo info : clips[c]) {
      const Transforms joints = reader.read_joint_transforms(info.name, 0, info.num_frames);
      const MatrixX3f frames = remake_frames(remake, reader.read_vertices(info.name, 0, info.num_frames), joints);
      info.ground_truth = GroundTruth::kVertices;
      writer.begin_clip(info);
      const int J = reader.num_joints();
      const int64_t N = remake.character.mesh.num_vertices();
      for (int t = 0; t < info.num_frames; ++t) {
        writer.append_frame(Transforms(joints.begin() + t * J, joints.begin() + (t + 1) * J),
                            frames.middleRows(t * N, N));
      }
      writer.end_clip();
      ++summary.clips;
      summary.frames += info.num_frames;
      if (options.progress) {
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const double rate = summary.clips / std::max(seconds, 1e-9);
        std::fprintf(stderr, "artist style: clips %d/%d, %.2f clips/s, ETA %.0fs\n", summary.clips, total, rate,
                     (total - summary.clips) / std::max(rate, 1e-9));
      }
    }
  }
  writer.commit();
  return summary;
}

}  // namespace amt
