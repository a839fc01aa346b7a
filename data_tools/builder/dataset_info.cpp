#include "data_tools/builder/dataset_info.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <vector>

#include "data_tools/builder/dataset_builder.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/error.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

/// A text table printed with columns padded to their widest cell; `right` marks numeric columns.
class Table {
 public:
  Table(std::vector<std::string> header, std::vector<bool> right) : right_(std::move(right)) {
    rows_.push_back(std::move(header));
  }
  void add(std::vector<std::string> row) { rows_.push_back(std::move(row)); }
  void print(std::ostream& out, const std::string& indent) const {
    std::vector<size_t> widths(rows_.front().size(), 0);
    for (const auto& row : rows_) {
      for (size_t c = 0; c < row.size(); ++c) widths[c] = std::max(widths[c], row[c].size());
    }
    for (const auto& row : rows_) {
      std::string line = indent;
      for (size_t c = 0; c < row.size(); ++c) {
        const std::string pad(widths[c] - row[c].size(), ' ');
        line += c > 0 ? "  " : "";
        line += right_[c] ? pad + row[c] : row[c] + (c + 1 < row.size() ? pad : "");
      }
      out << line << "\n";
    }
  }

 private:
  std::vector<bool> right_;
  std::vector<std::vector<std::string>> rows_;
};

std::string percent(int part, int whole) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f %%", whole > 0 ? 100.0 * part / whole : 0.0);
  return text;
}

std::string number(float value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", value);
  return text;
}

std::string count_of(size_t count, const char* noun) {
  return std::to_string(count) + " " + noun + (count == 1 ? "" : "s");
}

/// Bytes as "12.3 MB" (or kB below a megabyte).
std::string size_text(uint64_t bytes) {
  char text[32];
  if (bytes < 1000000) {
    std::snprintf(text, sizeof(text), "%.1f kB", bytes / 1e3);
  } else {
    std::snprintf(text, sizeof(text), "%.1f MB", bytes / 1e6);
  }
  return text;
}

/// Opens a shard and counts its characters, clips and frames, checking every one as print_dataset_info does. Any
/// error, and a shard that does not hold `character` with `clips` clips (what the manifest says; "" and -1 without
/// one), makes the shard damaged with that error as its problem.
void read_shard(const std::string& character, int clips, ShardSummary& shard) {
  try {
    const DatasetReader reader(shard.path);
    for (const std::string& name : reader.character_names()) shard.characters.add(reader.character_summary(name).split);
    shard.character_names = reader.character_names();
    for (const std::string& name : reader.clip_names()) {
      const ClipInfo clip = reader.clip_info(name);
      shard.clips.add(clip.split);
      shard.frames += clip.num_frames;
    }
    AMT_CHECK(character.empty() || reader.has_character(character), shard.path, ": no character '", character,
              "' (the manifest expects it in this shard)");
    AMT_CHECK(clips < 0 || static_cast<int>(reader.clip_names().size()) == clips, shard.path, ": ",
              reader.clip_names().size(), " clips, the manifest expects ", clips);
  } catch (const Error& e) {
    shard.status = ShardStatus::kDamaged;
    shard.problem = e.what();
    shard.characters = {};
    shard.clips = {};
    shard.frames = 0;
    shard.character_names.clear();
  }
}

// A rig's physics response (Rig::response) in a few words: its simulated bones and their median swing during the
// probe's sway and after it; "-" without a response.
std::string physics_text(const std::optional<Rig>& rig) {
  if (!rig || rig->response.rows() == 0) return "-";
  std::vector<float> during, after;
  for (Eigen::Index b = 0; b < rig->response.rows(); ++b) {
    if (!(rig->response(b, 0) > 0)) continue;
    during.push_back(rig->response(b, 1));
    after.push_back(rig->response(b, 2));
  }
  if (during.empty()) return "none simulated";
  const auto median = [](std::vector<float> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  char text[96];
  std::snprintf(text, sizeof(text), "%zu simulated, swing %.2f / %.2f", during.size(), median(during), median(after));
  return text;
}

}  // namespace

void print_dataset_info(const std::string& path, std::ostream& out) {
  const DatasetReader reader(path);
  out << path << "\n";
  out << "  format    " << kDatasetFormat << ", version " << reader.version()
      << (reader.version() < 2 ? " (no checksums: rebuild to have them)" : " (checksummed)") << "\n";
  out << "  fps       " << number(reader.fps()) << "\n";
  out << "  units     metres, up axis y\n";
  out << "  skeleton  " << reader.num_joints() << " joints\n";

  SplitCounts character_splits;
  Table characters({"name", "vertices", "faces", "apparel", "split", "rig", "physics (median swing during / after)"},
                   {false, true, true, true, false, false, false});
  for (const std::string& name : reader.character_names()) {
    const CharacterSummary c = reader.character_summary(name);
    character_splits.add(c.split);
    characters.add({c.name, std::to_string(c.num_vertices), std::to_string(c.num_faces),
                    percent(c.num_apparel_vertices, c.num_vertices), c.split,
                    c.num_bones > 0 ? std::to_string(c.num_bones) + " bones" : "-",
                    c.num_bones > 0 ? physics_text(reader.read_character(name).rig) : "-"});
  }
  out << "characters: " << reader.character_names().size() << " " << character_splits.text() << "\n";
  if (!reader.character_names().empty()) characters.print(out, "  ");

  SplitCounts clip_splits;
  long long frames = 0;
  Table clips({"name", "character", "motion", "frames", "ground truth", "split"},
              {false, false, false, true, false, false});
  for (const std::string& name : reader.clip_names()) {
    const ClipInfo clip = reader.clip_info(name);
    clip_splits.add(clip.split);
    frames += clip.num_frames;
    clips.add({clip.name, clip.character, clip.motion, std::to_string(clip.num_frames),
               ground_truth_name(clip.ground_truth), clip.split});
  }
  out << "clips: " << reader.clip_names().size() << " " << clip_splits.text() << "\n";
  if (!reader.clip_names().empty()) clips.print(out, "  ");

  out << "totals: " << count_of(reader.character_names().size(), "character") << " " << character_splits.text() << ", "
      << count_of(reader.clip_names().size(), "clip") << " " << clip_splits.text() << ", "
      << count_of(static_cast<size_t>(frames), "frame") << "\n";
}

const char* shard_status_name(ShardStatus status) {
  switch (status) {
    case ShardStatus::kRead:
      return "ok";
    case ShardStatus::kMissing:
      return "missing";
    case ShardStatus::kDamaged:
      return "damaged";
    case ShardStatus::kUnexpected:
      return "not in manifest";
    case ShardStatus::kDuplicate:
      return "duplicate";
  }
  return "?";
}

int DatasetFolderSummary::num_problems() const {
  return static_cast<int>(std::count_if(shards.begin(), shards.end(),
                                        [](const ShardSummary& s) { return s.status != ShardStatus::kRead; }));
}

DatasetFolderSummary summarise_dataset_folder(const std::string& dir) {
  std::error_code error;
  AMT_CHECK(fs::is_directory(dir, error), dir,
            ": no such folder (expected a dataset folder written by amt dataset build)");
  DatasetFolderSummary summary;
  summary.dir = dir;
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(dir, error)) {
    if (entry.path().extension() == ".h5" && entry.is_regular_file()) files.push_back(entry.path().string());
  }
  AMT_CHECK(!error, dir, ": cannot list the folder (", error.message(), ")");
  std::sort(files.begin(), files.end());

  const auto measure_size = [&](ShardSummary& shard) {
    shard.bytes = fs::file_size(shard.path, error);
    if (error) shard.bytes = 0;
  };
  std::set<std::string> named;
  std::map<std::string, std::string> shard_of;  // manifest character -> its shard's file name
  summary.has_manifest = fs::exists(fs::path(dir) / "manifest.json", error);
  if (summary.has_manifest) {
    const BuildManifest manifest = read_build_manifest(dir);
    summary.expected_characters = static_cast<int>(manifest.characters.size());
    summary.expected_clips_per_character = manifest.clips_per_character;
    for (size_t c = 0; c < manifest.characters.size(); ++c) {
      const PlannedCharacter& character = manifest.characters[c];
      ShardSummary shard;
      shard.path = shard_path(dir, character.name);
      shard.manifest_index = static_cast<int>(c);
      named.insert(shard.path);
      shard_of[character.name] = fs::path(shard.path).filename().string();
      if (fs::is_regular_file(shard.path, error)) {
        measure_size(shard);
        read_shard(character.name, manifest.clips_per_character, shard);
      } else {
        shard.status = ShardStatus::kMissing;
        const std::string part = part_path(dir, character.name);
        shard.problem = shard.path + ": missing (character " + std::to_string(c) + " of " +
                        std::to_string(manifest.characters.size()) +
                        ", made by the build process --shard i/n with i = " + std::to_string(c) + " mod n; " +
                        (fs::exists(part, error) ? fs::path(part).filename().string() +
                                                       " holds the clips committed so far: a build is running or was "
                                                       "interrupted, rerun it to finish)"
                                                 : "rerun that process: finished shards are kept)");
      }
      summary.shards.push_back(shard);
    }
  }
  for (const std::string& file : files) {
    if (named.count(file)) continue;
    ShardSummary shard;
    shard.path = file;
    measure_size(shard);
    read_shard("", -1, shard);
    if (summary.has_manifest && shard.status == ShardStatus::kRead) {
      shard.status = ShardStatus::kUnexpected;
      shard.problem = file + ": not named by manifest.json (a shard of another build? training reads every *.h5 here)";
      for (const std::string& name : shard.character_names) {
        const auto it = shard_of.find(name);
        if (it == shard_of.end()) continue;
        shard.status = ShardStatus::kDuplicate;
        shard.problem = file + ": holds " + name + " again, whose shard is " + it->second +
                        " (a duplicate: training would draw it twice as often; remove it)";
        break;
      }
    }
    summary.shards.push_back(shard);
  }
  AMT_CHECK(!summary.shards.empty(), dir,
            ": no manifest.json and no *.h5 shard (expected a dataset folder written by amt dataset build)");

  for (const ShardSummary& shard : summary.shards) {
    summary.bytes += shard.bytes;
    if (shard.status != ShardStatus::kRead) continue;
    summary.characters.train += shard.characters.train;
    summary.characters.test += shard.characters.test;
    summary.clips.train += shard.clips.train;
    summary.clips.test += shard.clips.test;
    summary.frames += shard.frames;
  }
  return summary;
}

void print_dataset_folder_summary(const DatasetFolderSummary& summary, std::ostream& out) {
  out << summary.dir << "\n";
  if (summary.has_manifest) {
    out << "  manifest  " << count_of(summary.expected_characters, "character") << " x "
        << count_of(summary.expected_clips_per_character, "clip") << " (manifest.json)\n";
  } else {
    out << "  manifest  none: the folder's *.h5 files are summarised, missing shards cannot be told\n";
  }
  Table shards({"shard", "characters", "clips", "frames", "size", "status"}, {false, false, false, true, true, false});
  for (const ShardSummary& shard : summary.shards) {
    const bool read = shard.status == ShardStatus::kRead || shard.status == ShardStatus::kUnexpected ||
                      shard.status == ShardStatus::kDuplicate;
    shards.add({fs::path(shard.path).filename().string(),
                read ? std::to_string(shard.characters.total()) + " " + shard.characters.text() : "-",
                read ? std::to_string(shard.clips.total()) + " " + shard.clips.text() : "-",
                read ? std::to_string(shard.frames) : "-", shard.bytes > 0 ? size_text(shard.bytes) : "-",
                shard_status_name(shard.status)});
  }
  const int problems = summary.num_problems();
  out << "shards: " << summary.shards.size() - problems << " of " << summary.shards.size() << " ok\n";
  shards.print(out, "  ");
  out << "totals: " << count_of(summary.characters.total(), "character") << " " << summary.characters.text()
      << ", " << count_of(summary.clips.total(), "clip") << " " << summary.clips.text() << ", "
      << count_of(static_cast<size_t>(summary.frames), "frame") << ", " << size_text(summary.bytes) << " on disk\n";
  if (problems == 0) {
    out << "missing, damaged or not in the manifest: none\n";
    return;
  }
  out << "missing, damaged or not in the manifest: " << problems << " of " << summary.shards.size() << " shards\n";
  for (const ShardSummary& shard : summary.shards) {
    if (shard.status != ShardStatus::kRead) out << "  " << shard.problem << "\n";
  }
}

void print_dataset_completeness(const DatasetFolderSummary& summary, std::ostream& out) {
  std::map<ShardStatus, int> count;
  for (const ShardSummary& shard : summary.shards) ++count[shard.status];
  out << "completeness: " << count_of(summary.expected_characters, "character") << " in manifest.json, "
      << count_of(count[ShardStatus::kRead], "shard") << " whole";
  if (summary.num_problems() == 0) {
    out << ": complete (every character has its shard, none is duplicated)\n";
    return;
  }
  for (const ShardStatus status :
       {ShardStatus::kMissing, ShardStatus::kDamaged, ShardStatus::kDuplicate, ShardStatus::kUnexpected}) {
    out << ", " << count[status] << " " << shard_status_name(status);
  }
  out << "\n";
  for (const ShardSummary& shard : summary.shards) {
    if (shard.status != ShardStatus::kRead) out << "  " << shard_status_name(shard.status) << ": " << shard.problem << "\n";
  }
}

}  // namespace amt
