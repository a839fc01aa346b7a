#pragma once
// `amt dataset build`: procedural characters (data_tools/builder/body_generator.h) dressed with MMD-style apparel
// (data_tools/builder/apparel.h), simulated under every clip of the motion library
// (data_tools/builder/motion_library.h) with Bullet (data_tools/builder/apparel_simulation.h), written as dataset
// shards (data_tools/formats/dataset_file.h).
//
// Output folder layout (format "amt-dataset-build", version 1):
//   DIR/manifest.json          the settings, the BVH files (names and sizes), the characters (name, seeds, split)
//                              and the clips (name, source, frames, split) of the whole dataset; written by the
//                              first run, checked by every later run and by every shard process
//   DIR/character-0007.h5      one complete shard per character: the character (with its rig) and all its clips,
//                              ground truth as rig_transforms; appears only when the character is finished
//   DIR/character-0007.json    the character's build record: body parameters, apparel pieces (kind, attachment
//                              joint, chain length, vertex range), vertex counts (read by dataset_quality.h)
//   DIR/character-0007.part    a character in progress (clips committed so far); renamed to .h5 when complete
//   *.tmp                      files being written (a .part's writer, the manifest); never read
// Only finished shards end in .h5, so a folder of shards can be read at any time (train/samples.h reads *.h5).
//
// Splits (pure functions of the seed and the counts): round(C / test_character_every) characters, at least one when
// C >= 2, are "test" (held-out characters); round(M / test_clip_every) of the M library clips, at least one when
// M >= 2, are held out for every character (held-out motions). A clip is "test" when its character or its library
// clip is held out; a test character's clips are all "test".
//
// Resume: a character's clips are simulated in batches of clips_per_commit; the .part file is committed (closed and
// renamed into place, data_tools/formats/dataset_file.h) after each batch, so an interrupted run loses at most one
// batch, and a rerun continues from the last commit. Because commits happen at the same clip indices in every run and
// each clip's simulation starts from a rebuilt world, an interrupted and resumed build writes the same bytes as an
// uninterrupted one.
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "data_tools/builder/apparel.h"
#include "data_tools/builder/apparel_simulation.h"
#include "data_tools/builder/motion_library.h"
#include "data_tools/builder/physics.h"
#include "data_tools/formats/pmx_import.h"

namespace amt {

// === Options

/// Which characters this process builds: those with index c % count == index.
struct ShardSpec {
  int index = 0;
  int count = 1;
};

/// Parses "i/n" (0 <= i < n, 1 <= n <= 100000). Throws amt::Error "--shard: expected i/n with 0 <= i < n, found
/// '...'" otherwise.
ShardSpec parse_shard(const std::string& text);

/// Everything that defines a built dataset, plus how this process takes part in building it.
struct DatasetBuildOptions {
  /// Output folder (created when missing).
  std::string out;
  /// Base seed of everything: character bodies and apparel, splits, procedural motions.
  uint64_t seed = 1;
  /// Number of procedural characters C (>= 0; >= 1 when no PMX model is given).
  int characters = 32;
  /// PMX models (files, or folders whose *.pmx files are all taken, sorted by name, not recursive): each becomes a
  /// character simulated with its own rigid bodies and joints (data_tools/builder/pmx_dataset.h), after the C
  /// procedural ones.
  std::vector<std::string> pmx;
  /// Metres per PMX unit of those models (finite, > 0): MMD's 0.08 by default. The physics runs in the models' own
  /// units; the shards store metres.
  float pmx_metres_per_unit = kPmxMetresPerUnit;
  /// A joint map file (data_tools/formats/joint_map.h: {canonical joint: bone name}) for the PMX models, overriding
  /// the MMD name table (models with English or otherwise unusual bone names); empty for the table alone. Recorded
  /// in the manifest by name and checksum.
  std::string character_joint_map;
  /// Folder of BVH files (every *.bvh); empty for procedural motions only.
  std::string motions;
  /// Number of procedural motion clips (>= 0).
  int procedural = 24;
  /// Frames per clip (>= 2).
  int frames = 120;
  /// Target vertex count of each body before dressing (generate_body: kMinBodyVertices..kMaxBodyVertices).
  int vertices = 5000;
  /// Frame rate of the clips.
  float fps = 30.0f;
  /// Seconds over which a clip blends from the rest pose into its motion (blend_from_rest).
  float blend_seconds = 0.75f;
  /// Seconds the apparel settles at the first pose before a clip is recorded.
  float settle_seconds = 1.0f;
  /// One in this many characters, and one in this many library clips, is held out for testing (>= 2).
  int test_character_every = 8;
  int test_clip_every = 8;
  /// Clips simulated between two commits of a character's .part file (>= 1). Part of the settings: commit points
  /// shape the file's bytes.
  int clips_per_commit = 8;
  /// Apparel choices of dress_character (the defaults are the dataset's).
  ApparelOptions apparel;
  /// Physics substep (seconds, in [1/2000, 1/30]) and solver iterations per substep (1..200). Finer than the
  /// PhysicsSettings defaults: fast mocap (dance, runs, jumps) swings the body bones far in one 1/120 s step, and
  /// the spring joints of light apparel chains then drift and snap back.
  float physics_step = 1.0f / 240.0f;
  int solver_iterations = 20;

  /// This process's share of the characters.
  ShardSpec shard;
  /// For tests: stop as if interrupted after this many clips were simulated in this run (uncommitted clips are
  /// lost, exactly as with a kill). Negative: never.
  int stop_after_clips = -1;
  /// Where progress lines go (null: nowhere).
  std::ostream* progress = nullptr;
};

/// Throws amt::Error naming the option unless every field is in range (see the comments above).
void validate_build_options(const DatasetBuildOptions& options);

// === Plan

/// One character of the dataset.
struct PlannedCharacter {
  /// "character-0007" (procedural) or "pmx-0002" (a PMX model): the group name in its shard and the shard's file stem.
  std::string name;
  /// Seeds of sample_body_params and dress_character (0 for a PMX model).
  uint64_t body_seed = 0;
  uint64_t apparel_seed = 0;
  /// "train" or "test".
  std::string split;
  /// The PMX model's path, empty for a procedural character.
  std::string pmx;
};

/// What a build makes: characters, library clips and their splits. A pure function of the options (and the BVH
/// files' contents).
struct DatasetPlan {
  std::vector<PlannedCharacter> characters;
  std::vector<MotionClip> clips;
  /// Per library clip: held out for every character.
  std::vector<bool> clip_held_out;

  /// Split of library clip k on character c: "test" when either is held out.
  std::string clip_split(int c, int k) const;
  /// Name of clip k of character c in its shard: "<character>__<library clip>".
  std::string clip_name(int c, int k) const;
};

/// The C procedural characters (names, seeds, splits), then one character per PMX model (list_pmx_files of
/// options.pmx; their own held-out set, so that adding models leaves the procedural splits alone), and the library
/// clips with their held-out flags.
DatasetPlan plan_dataset(const DatasetBuildOptions& options, std::vector<MotionClip> clips);

/// The PMX files of `paths`: a file as given, a folder's *.pmx files (any case) sorted by name. Throws amt::Error
/// naming the path when it does not exist, is a folder without a PMX file, or a file without the .pmx extension.
std::vector<std::string> list_pmx_files(const std::vector<std::string>& paths);

/// Indices [0, n) of which `held_out` are chosen, from a seeded Fisher-Yates shuffle: the held-out set.
/// held_out = n >= 2 ? max(1, round(n / every)) : 0. Deterministic on every platform.
std::vector<bool> held_out_set(int n, int every, uint64_t seed);

/// What DIR/manifest.json says a complete build holds: one shard per character (shard_path(DIR, name)), each with
/// every library clip.
struct BuildManifest {
  /// The characters in order, with their seeds and splits.
  std::vector<PlannedCharacter> characters;
  /// Library clips of every character's shard, and their frames summed.
  int clips_per_character = 0;
  int64_t frames_per_character = 0;
};

/// Reads DIR/manifest.json (as amt dataset info does). Throws amt::Error naming the file and the field when it cannot
/// be read, is not JSON, has another format or version, or a field read here is missing or out of range.
BuildManifest read_build_manifest(const std::string& dir);

/// File paths of a character's shard, build record and part file in `dir`.
std::string shard_path(const std::string& dir, const std::string& character);
std::string record_path(const std::string& dir, const std::string& character);
std::string part_path(const std::string& dir, const std::string& character);

// === Build

/// Figures of one run.
struct DatasetBuildReport {
  /// Characters of this shard, finished in this run, and found finished before it.
  int characters_total = 0, characters_built = 0, characters_skipped = 0;
  /// Clips of this shard, simulated and committed in this run, and found committed before it.
  int clips_total = 0, clips_built = 0, clips_skipped = 0;
  /// Frames simulated in this run (committed or not).
  int64_t frames = 0;
  /// Wall seconds of the run and of its stages: body generation, dressing, motion retargeting and forward
  /// kinematics, simulation, writing (dataset writer, commits, records).
  double seconds = 0, body_seconds = 0, dress_seconds = 0, motion_seconds = 0, simulate_seconds = 0, write_seconds = 0;
  /// Finished shards that failed verification (DatasetReader::verify), and part files of unfinished characters
  /// that could not be resumed (cut short, damaged), one message each, in character order; this run rebuilds them.
  std::vector<std::string> damaged;
  /// True when stop_after_clips ended the run early.
  bool interrupted = false;
  /// Dynamic apparel bodies per built character, averaged (0 when none was built).
  double mean_apparel_bodies = 0;
};

/// Builds this process's shards of the dataset into options.out. Steps: validate the options, build the motion
/// library (every BVH must import), plan, check or write DIR/manifest.json (a folder built with other settings is
/// rejected with the first setting that differs), then for each character of the shard that has no .h5 yet:
/// generate, dress, simulate the missing clips in batches (clips of a batch run in parallel on the OpenMP threads,
/// one Bullet world per thread) and commit, write the record and rename the part to .h5. Progress lines go to
/// options.progress. Bad input throws amt::Error before any file is touched; finished shards are never modified.
DatasetBuildReport build_dataset(const DatasetBuildOptions& options);

/// The motion library of the options (BVH folder, procedural clips, frames, fps), procedural motions drawn
/// from `seed`.
std::vector<MotionClip> motion_library_of(const DatasetBuildOptions& options, uint64_t seed);

/// Simulates one clip of a dressed character as the builder does: the rig's skinning matrices of every frame
/// (frames * B transforms, frame-major) under the body's joint transforms `joints` (frames * 22, forward
/// kinematics), with the options' physics step, solver iterations, frame rate and settle time. `simulator` is
/// built on first use and reused (one per thread).
Transforms simulate_clip(const DressedCharacter& dressed, const Transforms& joints, int frames,
                         const DatasetBuildOptions& options, std::unique_ptr<ApparelSimulator>& simulator);

/// Prints the run's summary: frames per second and the per-stage split of the wall time.
void print_build_report(const DatasetBuildReport& report, std::ostream& out);

}  // namespace amt
