#include "data_tools/dataset_info.h"

#include <algorithm>
#include <cstdio>
#include <vector>

#include "data_tools/dataset_file.h"

namespace amt {
namespace {

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

/// Train and test counts, printed as "(train 3, test 1)".
struct SplitCounts {
  int train = 0;
  int test = 0;
  void add(const std::string& split) { (split == "train" ? train : test) += 1; }
  std::string text() const { return "(train " + std::to_string(train) + ", test " + std::to_string(test) + ")"; }
};

}  // namespace

void print_dataset_info(const std::string& path, std::ostream& out) {
  const DatasetReader reader(path);
  out << path << "\n";
  out << "  format    " << kDatasetFormat << ", version " << kDatasetVersion << "\n";
  out << "  fps       " << number(reader.fps()) << "\n";
  out << "  units     metres, up axis y\n";
  out << "  skeleton  " << reader.num_joints() << " joints\n";

  SplitCounts character_splits;
  Table characters({"name", "vertices", "faces", "apparel", "split", "rig"}, {false, true, true, true, false, false});
  for (const std::string& name : reader.character_names()) {
    const CharacterSummary c = reader.character_summary(name);
    character_splits.add(c.split);
    characters.add({c.name, std::to_string(c.num_vertices), std::to_string(c.num_faces),
                    percent(c.num_apparel_vertices, c.num_vertices), c.split,
                    c.num_bones > 0 ? std::to_string(c.num_bones) + " bones" : "-"});
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

}  // namespace amt
