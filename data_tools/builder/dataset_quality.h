#pragma once
// Quality gates of a built dataset (issue 4, `amt dataset check DIR`): the ground truth must show dynamics a
// network has to learn, and must be clean. Measured over every clip of every finished shard of a folder written by
// data_tools/builder/dataset_builder.h (its *.h5 shards and character-*.json records):
//   - apparel lag: PMD_a of "apparel skinned rigidly to the body" (LBS with the character's body_weights and the
//     clip's joint_transforms) against the simulated ground truth, averaged over clips: 3 to 15 cm;
//   - no NaN or infinite value in joint transforms or ground-truth vertices;
//   - no apparel vertex farther from its piece's attachment joint than 1.5 x the piece's chain length (the
//     reach of its chains at rest, ApparelPiece::chain_length);
//   - no frame-to-frame apparel vertex jump above 1 m (30 m/s at 30 fps): a simulation glitch teleports vertices by
//     metres, while real motion stays below it (body joints in the fastest CMU dance clips move up to 46 cm per
//     frame, and hair-strand tips whipped by them up to 70 cm); reported beside it, the largest move
//     relative to the rigidly skinned vertex's move, |(v_t - v_t-1) - (r_t - r_t-1)|, and the body joints' largest
//     move, which tell a fast motion from a simulation jump;
//   - apparel vertices inside the posed body surface (the body's own closed mesh, generalized winding number):
//     under 2 % per frame on average (measured every penetration_stride-th frame);
//   - seams hold: vertices that coincide at rest (a model's duplicated seam vertices, within 0.1 mm,
//     data_tools/builder/artist_style.h coincident_pairs) stay together in the character's own ground truth: over
//     every pair and frame, 95th percentile at most 0.5 mm and largest at most 5 mm; a character that breaks
//     either is flagged with a one-line reason naming it.
// Plus a variety table (proportions, pose, apparel kinds, vertex counts per character) and a picture grid of the
// characters at rest (data_tools/formats/render.h).
#include <iosfwd>
#include <string>
#include <vector>

namespace amt {

// === Options

/// Choices of check_dataset and the gate bounds.
struct QualityOptions {
  /// Folder for report.md and characters.png (write_quality_report).
  std::string report_dir;
  /// Penetration is measured on frames 0, k, 2k, ... of each clip (>= 1).
  int penetration_stride = 10;
  /// Gate bounds: lag range (cm), largest stretch (in chain lengths), largest jump (cm per frame), largest mean
  /// penetration share.
  double min_lag_cm = 3.0, max_lag_cm = 15.0;
  double max_stretch = 1.5;
  double max_jump_cm = 100.0;
  double max_penetration_share = 0.02;
  /// Seam gap bounds (mm): 95th percentile and largest distance apart of vertices coincident at rest.
  double max_seam_gap_p95_mm = 0.5, max_seam_gap_mm = 5.0;
  /// Where progress lines go (null: nowhere).
  std::ostream* progress = nullptr;
};

// === Results

/// Figures of one character (over all its clips).
struct CharacterQuality {
  std::string name, split, shard;
  /// Body parameters from the character's build record (metres, ratios, degrees).
  double height = 0, head_ratio = 0, leg_ratio = 0, arm_angle_deg = 0;
  /// Apparel kinds of its pieces, comma-separated (e.g. "pleated_skirt, twin_tails").
  std::string apparel;
  int vertices = 0, apparel_vertices = 0, apparel_bodies = 0, clips = 0;
  int64_t frames = 0;
  /// Mean over clips of the rigid-skinning PMD_a (cm).
  double lag_cm = 0;
  /// Largest distance of an apparel vertex from its attachment joint, in chain lengths.
  double max_stretch = 0;
  /// Largest frame-to-frame apparel vertex displacement (cm).
  double max_jump_cm = 0;
  /// Mean share of apparel vertices inside the body over the measured frames.
  double penetration_share = 0;
  /// Non-finite values found.
  int64_t non_finite = 0;
  /// Pairs of vertices coincident at rest, and their distance apart over the ground truth's frames (mm): 95th
  /// percentile and largest (0 without pairs).
  int64_t seam_pairs = 0;
  double seam_gap_p95_mm = 0, seam_gap_max_mm = 0;
};

/// One gate's outcome.
struct QualityGate {
  std::string name;
  bool passed = false;
  /// The measured figure and the bound, e.g. "7.3 cm (bound 3 to 15 cm)".
  std::string figure;
};

/// Figures of a whole dataset folder.
struct DatasetQuality {
  std::string dir;
  std::vector<CharacterQuality> characters;
  int clips = 0;
  int64_t frames = 0, penetration_frames = 0;
  /// Mean over all clips of the rigid-skinning PMD_a (cm).
  double lag_cm = 0;
  int64_t non_finite = 0;
  double max_stretch = 0, max_jump_cm = 0;
  /// Where the largest stretch and jump happened ("clip frame t").
  std::string max_stretch_where, max_jump_where;
  /// Largest frame-to-frame apparel move relative to its rigidly skinned move (cm), for information.
  double max_relative_jump_cm = 0;
  /// Largest frame-to-frame move of a body joint (cm), for comparison with the apparel's: the motions' own speed.
  double max_joint_jump_cm = 0;
  std::string max_joint_jump_where;
  /// Mean share of apparel vertices inside the body over the measured frames.
  double penetration_share = 0;
  /// One line per character whose coincident vertices move apart in its ground truth, naming it and the figures.
  std::vector<std::string> flagged;
  std::vector<QualityGate> gates;

  /// Number of gates that failed.
  int failed_gates() const;
};

// === Checks

/// Measures every clip of every *.h5 shard of `dir` (the character records character-*.json beside them give body
/// parameters, apparel pieces and the body's own vertex and face ranges) and evaluates the gates. Throws amt::Error
/// for a folder without shards, a shard without its record, or unreadable files.
DatasetQuality check_dataset(const std::string& dir, const QualityOptions& options);

/// Writes options.report_dir/report.md (gates, dataset figures, variety table) and options.report_dir/characters.png
/// (the characters at rest, rendered at one scale, apparel in a cloth colour), each atomically.
void write_quality_report(const DatasetQuality& quality, const QualityOptions& options);

/// One line per gate: "PASS apparel lag: 7.3 cm (bound 3 to 15 cm)", one "FLAG " line per flagged character, then
/// one INFO line on variety.
void print_gates(const DatasetQuality& quality, std::ostream& out);

}  // namespace amt
