#pragma once
// `amt dataset info`: a human-readable summary of a dataset file or of a dataset folder
// (docs/dataset.md, "The dataset file (HDF5, format `amt-dataset`, version 2)").
#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

namespace amt {

/// Prints a summary of the dataset file at `path` to `out`: format, version, fps, units, up axis and
/// skeleton size; one line per character (vertices, faces, apparel share = % of vertices with mask
/// 1, split, rig bones) and per clip (character, motion, frames, ground-truth form, split); totals
/// of characters, clips and frames with their train / test split counts. Every character and clip
/// is checked as it is listed (DatasetReader::character_summary and clip_info); bad input throws
/// amt::Error.
void print_dataset_info(const std::string& path, std::ostream& out);

/// Train and test counts of characters or clips.
struct SplitCounts {
  int train = 0;
  int test = 0;
  void add(const std::string& split) { (split == "train" ? train : test) += 1; }
  int total() const { return train + test; }
  /// "(train 3, test 1)".
  std::string text() const { return "(train " + std::to_string(train) + ", test " + std::to_string(test) + ")"; }
};

/// What became of one shard of a dataset folder.
enum class ShardStatus {
  /// Read and counted.
  kRead,
  /// Named by the manifest, not in the folder.
  kMissing,
  /// Cannot be read (damaged, truncated, not a dataset file), or does not hold what the manifest says.
  kDamaged,
  /// Readable, but not named by the manifest.
  kUnexpected,
  /// Readable, not named by the manifest, and holding a character of the manifest again (a copy, or the
  /// same character built twice under another name): training would draw it twice as often.
  kDuplicate,
};

/// "ok", "missing", "damaged", "not in manifest" or "duplicate".
const char* shard_status_name(ShardStatus status);

/// One shard of a dataset folder and what reading it found.
struct ShardSummary {
  std::string path;
  ShardStatus status = ShardStatus::kRead;
  /// Unless the shard was read: why, one line naming the file (for a damaged shard the reader's error).
  std::string problem;
  /// Size on disk in bytes; 0 when missing.
  uint64_t bytes = 0;
  /// What the shard holds (zero unless it was read).
  SplitCounts characters, clips;
  int64_t frames = 0;
  /// The characters it holds (empty unless it was read).
  std::vector<std::string> character_names;
  /// For a shard the manifest names: its character's index c there (the build process --shard i/n with
  /// i = c mod n makes it); -1 otherwise.
  int manifest_index = -1;
};

/// A dataset folder written by amt dataset build: every shard its manifest.json names, each opened and every
/// character and clip checked as print_dataset_info does, plus any other *.h5 in the folder (a problem: training
/// would read it, the manifest does not know it; a duplicate when it holds a character of the manifest). A folder
/// without manifest.json is summarised from its *.h5 files; then missing shards cannot be told.
struct DatasetFolderSummary {
  std::string dir;
  bool has_manifest = false;
  /// What the manifest expects: characters (one shard each) and clips per character.
  int expected_characters = 0;
  int expected_clips_per_character = 0;
  /// The shards in manifest order, then the others sorted by name.
  std::vector<ShardSummary> shards;
  /// Totals over the shards that were read; bytes over every shard present.
  SplitCounts characters, clips;
  int64_t frames = 0;
  uint64_t bytes = 0;

  /// Shards not read: missing, damaged or unexpected.
  int num_problems() const;
};

/// Summarises the dataset folder `dir`. A damaged shard is reported in its ShardSummary, not thrown; throws amt::Error
/// when `dir` is not a folder, its manifest.json cannot be read, or it has neither a manifest nor a *.h5 file.
DatasetFolderSummary summarise_dataset_folder(const std::string& dir);

/// Prints the folder summary: what the manifest expects, one row per shard (splits, clips, frames, size, status),
/// the totals, and every problem on a line of its own.
void print_dataset_folder_summary(const DatasetFolderSummary& summary, std::ostream& out);

/// Prints whether the shards of a folder with a manifest, built by one or many `--shard i/n` processes, add up to
/// the dataset the manifest describes: "completeness: complete, ..." or one count line per kind of problem
/// (missing, damaged, duplicate, not in the manifest) and every problem on a line of its own.
void print_dataset_completeness(const DatasetFolderSummary& summary, std::ostream& out);

}  // namespace amt
