#include "data_tools/builder/dataset_quality.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <nlohmann/json.hpp>
#include <ostream>
#include <set>
#include <sstream>

#include "data_tools/builder/artist_style.h"
#include "data_tools/formats/atomic_file.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/formats/render.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/metrics.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/winding_number.h"

namespace amt {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// A piece of a character record: the apparel vertices in [first, end) hang from `joint` with reach `chain_length`.
struct PieceRecord {
  std::string kind;
  int joint = 0;
  double chain_length = 0;
  int first = 0, end = 0;
};

struct CharacterRecord {
  json params;
  int body_vertices = 0, body_faces = 0, apparel_bodies = 0;
  std::vector<PieceRecord> pieces;
};

CharacterRecord read_record(const std::string& path) {
  std::error_code error;
  AMT_CHECK(std::filesystem::exists(path, error), path,
            ": missing (expected the build record written beside each shard by amt dataset build)");
  check_input_file(path, "the build record written beside each shard by amt dataset build");
  std::ifstream in(path, std::ios::binary);
  AMT_CHECK(in.good(), path, ": missing (expected the build record written beside each shard by amt dataset build)");
  std::stringstream text;
  text << in.rdbuf();
  CharacterRecord record;
  try {
    const json doc = json::parse(text.str());
    AMT_CHECK(doc.value("format", "") == "amt-character-record" && doc.value("version", 0) == 1, path,
              ": format: expected amt-character-record version 1, found ", doc.value("format", "none"), " version ",
              doc.value("version", 0));
    record.params = doc.at("params");
    record.body_vertices = doc.at("body_vertices").get<int>();
    record.body_faces = doc.at("body_faces").get<int>();
    record.apparel_bodies = doc.at("apparel_bodies").get<int>();
    for (const json& p : doc.at("pieces")) {
      record.pieces.push_back({p.at("kind").get<std::string>(), p.at("attachment_joint").get<int>(),
                               p.at("chain_length").get<double>(), p.at("first_vertex").get<int>(),
                               p.at("end_vertex").get<int>()});
    }
  } catch (const json::exception& e) {
    fail(path, ": expected a character record, found invalid JSON or a missing field (", e.what(), ")");
  }
  return record;
}

std::string fixed(double value, int digits) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(digits) << value;
  return out.str();
}

}  // namespace

int DatasetQuality::failed_gates() const {
  return static_cast<int>(std::count_if(gates.begin(), gates.end(), [](const QualityGate& g) { return !g.passed; }));
}

DatasetQuality check_dataset(const std::string& dir, const QualityOptions& options) {
  AMT_CHECK(options.penetration_stride >= 1, "dataset check: --penetration-stride: expected >= 1, found ",
            options.penetration_stride);
  std::vector<std::string> shards;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(dir, error)) {
    if (entry.path().extension() == ".h5" && entry.is_regular_file()) shards.push_back(entry.path().string());
  }
  AMT_CHECK(!error, dir, ": cannot list the folder: ", error.message());
  AMT_CHECK(!shards.empty(), dir, ": no shard (expected *.h5 files written by amt dataset build)");
  std::sort(shards.begin(), shards.end());

  DatasetQuality q;
  q.dir = dir;
  double lag_sum = 0, share_sum = 0;
  int lag_clips = 0;
  const auto start = std::chrono::steady_clock::now();
  for (size_t s = 0; s < shards.size(); ++s) {
    const std::string& shard = shards[s];
    const DatasetReader reader(shard);
    const std::string record_file = (fs::path(shard).replace_extension(".json")).string();
    const CharacterRecord record = read_record(record_file);
    for (const std::string& name : reader.character_names()) {
      const CharacterData character = reader.read_character(name);
      const int N = character.mesh.num_vertices(), J = reader.num_joints();
      AMT_CHECK(record.body_vertices >= 4 && record.body_vertices <= N && record.body_faces >= 4 &&
                    record.body_faces <= character.mesh.num_faces(),
                record_file, ": body_vertices / body_faces: expected within the character's ", N, " vertices and ",
                character.mesh.num_faces(), " faces, found ", record.body_vertices, " and ", record.body_faces);
      CharacterQuality cq;
      cq.name = name;
      cq.split = character.split;
      cq.shard = fs::path(shard).filename().string();
      cq.height = record.params.value("height", 0.0);
      cq.head_ratio = record.params.value("head_ratio", 0.0);
      cq.leg_ratio = record.params.value("leg_ratio", 0.0);
      cq.arm_angle_deg = record.params.value("arm_angle_deg", 0.0);
      cq.vertices = N;
      cq.apparel_bodies = record.apparel_bodies;
      for (const uint8_t m : character.apparel_mask) cq.apparel_vertices += m;
      for (const PieceRecord& piece : record.pieces) cq.apparel += (cq.apparel.empty() ? "" : ", ") + piece.kind;

      // Per apparel vertex: attachment joint and reach (from the pieces' vertex ranges).
      std::vector<int> apparel, joint_of;
      std::vector<double> reach_of;
      for (int i = 0; i < N; ++i) {
        if (!character.apparel_mask[i]) continue;
        const PieceRecord* owner = nullptr;
        for (const PieceRecord& piece : record.pieces) {
          if (i >= piece.first && i < piece.end) owner = &piece;
        }
        AMT_CHECK(owner && owner->joint >= 0 && owner->joint < J && owner->chain_length > 0, record_file,
                  ": apparel vertex ", i, " of ", name,
                  ": expected a piece with an attachment joint and a chain length");
        apparel.push_back(i);
        joint_of.push_back(owner->joint);
        reach_of.push_back(owner->chain_length);
      }
      const int A = static_cast<int>(apparel.size());
      const SparseWeights body_weights = sparsify_weights(character.body_weights);
      const MatrixX3i body_faces = character.mesh.F.topRows(record.body_faces);

      double character_lag = 0, character_share = 0;
      int character_share_frames = 0;
      // Seams: the pairs coincident at rest, measured in every finite ground-truth frame.
      SeparationAccumulator seams(coincident_pairs(character.mesh.V, character.mesh.F), MatrixX2i(0, 2));
      for (const std::string& clip : reader.clip_names()) {
        const ClipInfo info = reader.clip_info(clip);
        if (info.character != name) continue;
        const int T = info.num_frames;
        const Transforms joints = reader.read_joint_transforms(clip, 0, T);
        const MatrixX3f truth = reader.read_vertices(clip, 0, T);
        double clip_lag = 0;
        int lag_frames = 0;
        MatrixX3f rigid, previous_rigid, frame(N, 3), previous(N, 3), apparel_points(A, 3);
        for (int t = 0; t < T; ++t) {
          frame = truth.middleRows(static_cast<Eigen::Index>(t) * N, N);
          const Transforms pose(joints.begin() + static_cast<ptrdiff_t>(t) * J,
                                joints.begin() + static_cast<ptrdiff_t>(t + 1) * J);
          for (const Transform34& m : pose) cq.non_finite += (!m.allFinite()) ? 1 : 0;
          for (int j = 0; t > 0 && j < J; ++j) {
            const double move = 100.0 * (pose[j].col(3) - joints[static_cast<size_t>(t - 1) * J + j].col(3)).norm();
            if (move > q.max_joint_jump_cm) {
              q.max_joint_jump_cm = move;
              q.max_joint_jump_where = clip + " frame " + std::to_string(t) + " " + character.skeleton.names[j];
            }
          }
          if (!frame.allFinite()) {
            cq.non_finite += static_cast<int64_t>((!frame.array().isFinite()).count());
            continue;
          }
          seams.add_frame(frame, character.mesh.V);  // the gaps opened since rest
          linear_blend_skinning(character.mesh.V, body_weights, skinning_matrices(character.skeleton, pose), rigid);
          const double pmd = point_mesh_distance_cm(rigid, frame, &character.apparel_mask, 1);
          if (std::isfinite(pmd)) clip_lag += pmd, ++lag_frames;
          for (int a = 0; a < A; ++a) {
            const int i = apparel[a];
            const Eigen::Vector3f p = frame.row(i).transpose();
            apparel_points.row(a) = frame.row(i);
            const double stretch = (p - pose[joint_of[a]].col(3)).norm() / reach_of[a];
            if (stretch > cq.max_stretch) {
              cq.max_stretch = stretch;
              if (stretch > q.max_stretch)
                q.max_stretch = stretch, q.max_stretch_where = clip + " frame " + std::to_string(t);
            }
            if (t > 0) {
              const double jump = 100.0 * (frame.row(i) - previous.row(i)).norm();
              // For comparison: the move relative to the rigidly carried vertex's move.
              const double relative =
                  100.0 * ((frame.row(i) - previous.row(i)) - (rigid.row(i) - previous_rigid.row(i))).norm();
              if (relative > q.max_relative_jump_cm) q.max_relative_jump_cm = relative;
              if (jump > cq.max_jump_cm) {
                cq.max_jump_cm = jump;
                if (jump > q.max_jump_cm) q.max_jump_cm = jump, q.max_jump_where = clip + " frame " + std::to_string(t);
              }
            }
          }
          if (A > 0 && t % options.penetration_stride == 0) {
            const WindingNumberTree body(frame.topRows(record.body_vertices), body_faces);
            character_share += penetration(apparel_points, body).share();
            ++character_share_frames;
          }
          previous = frame;
          previous_rigid = rigid;
        }
        if (lag_frames > 0) {
          clip_lag /= lag_frames;
          character_lag += clip_lag;
          lag_sum += clip_lag;
          ++lag_clips;
        }
        ++cq.clips;
        cq.frames += T;
      }
      cq.lag_cm = cq.clips > 0 ? character_lag / cq.clips : 0.0;
      const SeparationScores seam = seams.result();
      cq.seam_pairs = seam.pairs;
      if (seam.pair_frames > 0)
        cq.seam_gap_p95_mm = 10 * seam.seam_gap_p95_cm, cq.seam_gap_max_mm = 10 * seam.seam_gap_max_cm;
      if (cq.seam_gap_p95_mm > options.max_seam_gap_p95_mm || cq.seam_gap_max_mm > options.max_seam_gap_mm)
        q.flagged.push_back(name + " (" + cq.shard +
                            "): coincident vertices move apart in its own ground truth: 95th "
                            "percentile " +
                            fixed(cq.seam_gap_p95_mm, 2) + " mm, largest " + fixed(cq.seam_gap_max_mm, 2) +
                            " mm over " + std::to_string(cq.seam_pairs) + " pairs (bounds " +
                            fixed(options.max_seam_gap_p95_mm, 1) + " mm, " + fixed(options.max_seam_gap_mm, 1) +
                            " mm)");
      cq.penetration_share = character_share_frames > 0 ? character_share / character_share_frames : 0.0;
      share_sum += character_share;
      q.penetration_frames += character_share_frames;
      q.non_finite += cq.non_finite;
      q.clips += cq.clips;
      q.frames += cq.frames;
      q.characters.push_back(cq);
    }
    if (options.progress) {
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      *options.progress << "check: shard " << s + 1 << "/" << shards.size() << ", " << q.frames << " frames, "
                        << fixed(q.frames / std::max(elapsed, 1e-9), 0) << " frames/s, ETA "
                        << fixed(elapsed / (s + 1) * (shards.size() - s - 1), 0) << " s\n";
    }
  }
  q.lag_cm = lag_clips > 0 ? lag_sum / lag_clips : 0.0;
  q.penetration_share = q.penetration_frames > 0 ? share_sum / q.penetration_frames : 0.0;

  const QualityOptions& o = options;
  q.gates.push_back({"apparel lag", q.lag_cm >= o.min_lag_cm && q.lag_cm <= o.max_lag_cm,
                     "PMD_a of rigid skinning vs simulation " + fixed(q.lag_cm, 2) + " cm over " +
                         std::to_string(q.clips) + " clips (bound " + fixed(o.min_lag_cm, 0) + " to " +
                         fixed(o.max_lag_cm, 0) + " cm)"});
  q.gates.push_back({"no NaN", q.non_finite == 0,
                     std::to_string(q.non_finite) + " non-finite values in " + std::to_string(q.frames) + " frames"});
  q.gates.push_back({"no explosion", q.max_stretch <= o.max_stretch,
                     "largest apparel distance from its attachment " + fixed(q.max_stretch, 2) +
                         " chain lengths (bound " + fixed(o.max_stretch, 2) + ")" +
                         (q.max_stretch_where.empty() ? "" : ", at " + q.max_stretch_where)});
  q.gates.push_back({"no jump", q.max_jump_cm <= o.max_jump_cm,
                     "largest frame-to-frame apparel vertex move " + fixed(q.max_jump_cm, 1) + " cm (bound " +
                         fixed(o.max_jump_cm, 0) + " cm per frame at 30 fps)" +
                         (q.max_jump_where.empty() ? "" : ", at " + q.max_jump_where) +
                         "; relative to the rigidly skinned move up to " + fixed(q.max_relative_jump_cm, 1) +
                         " cm, body joints up to " + fixed(q.max_joint_jump_cm, 1) + " cm per frame" +
                         (q.max_joint_jump_where.empty() ? "" : " (" + q.max_joint_jump_where + ")")});
  q.gates.push_back({"penetration", q.penetration_share < o.max_penetration_share,
                     fixed(100.0 * q.penetration_share, 2) + " % of apparel vertices inside the body per frame over " +
                         std::to_string(q.penetration_frames) + " frames (bound " +
                         fixed(100.0 * o.max_penetration_share, 0) + " %)"});
  int64_t seam_pairs = 0;
  int seam_characters = 0;
  for (const CharacterQuality& c : q.characters) seam_pairs += c.seam_pairs, seam_characters += c.seam_pairs > 0;
  q.gates.push_back({"seams hold", q.flagged.empty(),
                     std::to_string(q.flagged.size()) + " of " + std::to_string(seam_characters) +
                         " characters with coincident vertices (" + std::to_string(seam_pairs) +
                         " pairs) move them apart in their ground truth (bounds: 95th percentile " +
                         fixed(o.max_seam_gap_p95_mm, 1) + " mm, largest " + fixed(o.max_seam_gap_mm, 1) + " mm)" +
                         (q.flagged.empty() ? "" : "; first: " + q.flagged.front())});
  return q;
}

void print_gates(const DatasetQuality& q, std::ostream& out) {
  for (const QualityGate& gate : q.gates) {
    out << (gate.passed ? "PASS " : "FAIL ") << gate.name << ": " << gate.figure << "\n";
  }
  for (const std::string& flag : q.flagged) out << "FLAG " << flag << "\n";
  std::set<std::string> kinds;
  double low = 1e9, high = 0;
  for (const CharacterQuality& c : q.characters) {
    low = std::min(low, c.height), high = std::max(high, c.height);
    std::stringstream list(c.apparel);
    std::string kind;
    while (std::getline(list, kind, ',')) kinds.insert(kind.substr(kind.find_first_not_of(' ')));
  }
  out << "INFO variety: " << q.characters.size() << " characters, heights " << fixed(low, 2) << " to " << fixed(high, 2)
      << " m, " << kinds.size() << " apparel kinds\n";
}

void write_quality_report(const DatasetQuality& q, const QualityOptions& options) {
  AMT_CHECK(!options.report_dir.empty(), "dataset check: --report: expected a folder, found none");
  std::ostringstream md;
  md << "# Dataset quality: " << q.dir << "\n\n"
     << q.characters.size() << " characters, " << q.clips << " clips, " << q.frames << " frames.\n\n"
     << "## Gates\n\n| gate | result | figure |\n|---|---|---|\n";
  for (const QualityGate& gate : q.gates) {
    md << "| " << gate.name << " | " << (gate.passed ? "PASS" : "FAIL") << " | " << gate.figure << " |\n";
  }
  if (!q.flagged.empty()) {
    md << "\n## Flagged characters\n\n";
    for (const std::string& flag : q.flagged) md << "- " << flag << "\n";
  }
  md << "\n## Characters\n\n![characters](characters.png)\n\n"
     << "| character | split | height (m) | head ratio | leg ratio | pose | apparel | vertices | apparel vertices | "
        "apparel bodies | clips | lag (cm) | max stretch | max jump (cm) | penetration (%) | seam pairs | seam gap "
        "p95 / max (mm) |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const CharacterQuality& c : q.characters) {
    const std::string pose = c.arm_angle_deg < 10 ? "T-pose" : "A-pose " + fixed(c.arm_angle_deg, 0) + " deg";
    md << "| " << c.name << " | " << c.split << " | " << fixed(c.height, 2) << " | " << fixed(c.head_ratio, 3) << " | "
       << fixed(c.leg_ratio, 2) << " | " << pose << " | " << c.apparel << " | " << c.vertices << " | "
       << c.apparel_vertices << " | " << c.apparel_bodies << " | " << c.clips << " | " << fixed(c.lag_cm, 2) << " | "
       << fixed(c.max_stretch, 2) << " | " << fixed(c.max_jump_cm, 1) << " | " << fixed(100.0 * c.penetration_share, 2)
       << " | " << c.seam_pairs << " | " << fixed(c.seam_gap_p95_mm, 2) << " / " << fixed(c.seam_gap_max_mm, 2)
       << " |\n";
  }
  write_file_atomically((fs::path(options.report_dir) / "report.md").string(), md.str());

  // The characters at rest, at one scale so that their heights compare.
  double tallest = 0;
  for (const CharacterQuality& c : q.characters) tallest = std::max(tallest, c.height);
  RenderOptions render;
  render.width = 160;
  render.height = 256;
  render.world_height = static_cast<float>(std::max(0.5, tallest * 1.08));
  std::vector<Image> images;
  for (const CharacterQuality& c : q.characters) {
    const DatasetReader reader((fs::path(q.dir) / c.shard).string());
    const CharacterData character = reader.read_character(c.name);
    images.push_back(render_character(character.mesh, character.apparel_mask, render));
  }
  if (!images.empty()) {
    const int columns = std::min<int>(8, static_cast<int>(images.size()));
    write_png(image_grid(images, columns), (fs::path(options.report_dir) / "characters.png").string());
  }
}

}  // namespace amt
