#pragma once
// Training samples streamed from dataset shards (docs/dataset.md, "The dataset file"): per-character tensors
// computed once from the rest mesh and cached, and per-sample frame windows read from HDF5 as
// hyperslabs (a clip is never loaded whole). Which sample comes k-th is a pure function of
// (seed, k), so a run resumed at step s sees exactly the samples an uninterrupted run sees; the
// prefetching loader threads change only when a sample is read, never which.
#include <ATen/core/Tensor.h>

#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "data_tools/geometry/types.h"
#include "models/apparel_dynamics.h"
#include "models/apparel_handles.h"
#include "models/checkpoint.h"

namespace amt {

// === Shards

/// The shard files named by `inputs`, in the given order: a file stays as it is, a directory is
/// replaced by its *.h5 files sorted by name. Throws amt::Error for no inputs, a missing path or a
/// directory without *.h5 files ("data/: no shards (expected *.h5 dataset files)").
std::vector<std::string> resolve_shards(const std::vector<std::string>& inputs);

/// A fingerprint of a training set: "fnv1a64:<16 hex digits>" over each shard's file name (without
/// its folder, so moving the data keeps it), its size in bytes, and the J joint names. Throws
/// amt::Error when a shard is missing.
std::string data_fingerprint(const std::vector<std::string>& shards, const std::vector<std::string>& joint_names);

// === Per-character tensors

/// What the trainers need from one character's rest mesh; computed once and shared (read-only).
struct CharacterTensors {
  /// Shard file and character group name.
  std::string shard, name;
  /// V (N, 3) float rest positions, metres.
  at::Tensor V;
  /// joints (J, 3) float rest joint positions, metres.
  at::Tensor joints;
  /// edges (E, 2) int64 unique mesh edges (i < j).
  at::Tensor edges;
  /// apparel_mask (N) bool, true for apparel vertices.
  at::Tensor apparel_mask;
  /// apparel_ids (N_a) and body_ids (N_b) int64 vertex indices of the two parts, ascending.
  at::Tensor apparel_ids, body_ids;
  /// body_weights (N, J) float ground-truth skinning weights, rows sum to 1.
  at::Tensor body_weights;
  /// body_edges (E_b, 2) int64 mesh edges between body vertices, numbered by position in body_ids.
  at::Tensor body_edges;
  /// apparel_edges (E_a, 2) int64 mesh edges between apparel vertices, numbered by position in apparel_ids.
  at::Tensor apparel_edges;
  /// apparel_neighbors (N_a, K_max) int64 neighbour table of the apparel graph (neighbor_table).
  at::Tensor apparel_neighbors;
  /// apparel_anchor_weights (N_a, J) float: the ground-truth weights of each apparel vertex's anchor
  /// body vertex (apparel_anchor_weights_for `apparel_anchor`: where its piece attaches, or its
  /// nearest body vertex), which skin the apparel network's anchor S^(t).
  std::string apparel_anchor;
  at::Tensor apparel_anchor_weights;
  /// graph_edges (E', 2) int64 the linked topology (linked_topology: mesh edges, seam links, proximity
  /// links between apparel pieces), on which the apparel graph, attachment paths and handles are built.
  at::Tensor graph_edges;
  /// The apparel module's handles (SampleSourceOptions::handle_spacing > 0); undefined rows otherwise.
  ApparelRig apparel_rig;
  /// The apparel module's nodes: every apparel vertex, or the handles' vertices. apparel_node_ids (H) int64
  /// vertex indices; apparel_node_edges (E_h, 2) int64 numbered by node (apparel_edges, or the rig's edges).
  at::Tensor apparel_node_ids, apparel_node_edges;
  /// The apparel dynamics module's per-character inputs over its nodes (frame joints, rest channels,
  /// neighbours: apparel_neighbors, or the graph over the handles, handle_graph).
  ApparelGraph apparel_graph;
  /// G_body (N_b, J) float geodesic distances (metres) over the body mesh, the faces whose three
  /// vertices are body vertices (geodesic_distances); computed only for the skinning module, else undefined.
  at::Tensor G_body;
  /// segmenter_features (N, kSegmentationFeatures) float shape features of the rest mesh
  /// (segmentation_features); computed only for the segmenter, else undefined.
  at::Tensor segmenter_features;
  /// segmenter_weights (N) float, the segmenter's per-vertex loss weights (held_rows_weights with
  /// SampleSourceOptions::segmenter_held_weight); undefined when that weight is 1. Variants carry theirs.
  at::Tensor segmenter_weights;
  /// With SampleSourceOptions::segmenter_variants: the character remade for augmentation, each with its
  /// own V (N', 3), features (N', kSegmentationFeatures) and apparel mask (N') bool
  /// (data_tools/builder/segmenter_augmentation.h): open parts, bare body, bare open parts; and with
  /// SampleSourceOptions::segmenter_artist_vertices the artist-style remake (data_tools/builder/artist_style.h).
  struct SegmenterVariant {
    std::string what;
    at::Tensor V, features, apparel_mask, weights;
  };
  std::vector<SegmenterVariant> segmenter_variants;
};

/// Per-vertex loss weights of the segmenter: `weight` on the held rows, the body vertices of the mesh's connected
/// parts that also hold apparel (where a piece hangs from the body: a body bone holds them rigidly, and the
/// apparel module needs them body, hang_apparel_pieces), 1 elsewhere. mask (N) 0/1, F (F, 3).
at::Tensor held_rows_weights(const std::vector<uint8_t>& mask, const MatrixX3i& F, double weight);

// === Samples

/// One training sample: a character and, except for the segmenter, a window of consecutive frames.
struct TrainingSample {
  /// The character, shared with every other sample of it.
  std::shared_ptr<const CharacterTensors> character;
  /// The clip the frames come from (empty for the segmenter) and the window's first frame.
  std::string clip;
  int first_frame = 0;
  /// joint_transforms (F, J, 3, 4) float [R_j | t_j] of the window's frames (F = 0: undefined).
  at::Tensor joint_transforms;
  /// vertices (F, N, 3) float ground-truth positions of the window's frames (F = 0: undefined).
  at::Tensor vertices;
};

/// What a SampleSource draws.
struct SampleSourceOptions {
  /// The module the samples are for: the segmenter draws characters; skinning draws windows of
  /// clips of characters with body vertices; apparel windows of characters with apparel vertices;
  /// the refiner windows of any clip.
  ModuleKind kind = ModuleKind::kSegmenter;
  /// F, frames per window (ignored by the segmenter). Clips shorter than F are skipped.
  int frames = 10;
  /// Only characters (segmenter) or clips (others) of this split are drawn.
  std::string split = "train";
  /// Seed of the sample order.
  uint64_t seed = 1;
  /// Share of windows that start at their clip's first frame instead of a uniformly drawn one (the
  /// apparel module's rollouts from the rest pose); which windows do is a function of (seed, k) too.
  double clip_start_fraction = 0.0;
  /// Compute CharacterTensors::G_body for every module, not only for skinning (the refiner needs it
  /// when B̂ comes from a trained skinning predictor).
  bool geodesics = false;
  /// The segmenter's inputs (ApparelSegmenterOptions::inputs): which features segmenter_features holds
  /// (segmenter_input_features).
  std::string segmenter_inputs = "shape";
  /// The segmenter: also make CharacterTensors::segmenter_variants.
  bool segmenter_variants = false;
  /// With segmenter_variants: also the "artist_style" variant, the character remade by artist_style_character
  /// subdivided to this many vertices (0: not subdivided; < 0: no remake), seeded by `seed` and the character's name.
  int segmenter_artist_vertices = -1;
  /// The segmenter: loss weight of the held rows (held_rows_weights); 1 for none.
  double segmenter_held_weight = 1.0;
  /// The apparel anchor of CharacterTensors::apparel_anchor_weights (ApparelDynamicsOptions::anchor):
  /// "nearest" (the global form's and the earlier local checkpoints') or "attachment".
  std::string apparel_anchor = "nearest";
  /// The apparel module's handle spacing (ApparelDynamicsOptions::handle_spacing): > 0 makes the handles of
  /// every character (CharacterTensors::apparel_rig) and the module's graph over them.
  double handle_spacing = 0.0;
  /// When set: the body weights (N_b, J) that skin the apparel anchors and build the apparel graph,
  /// from a character's tensors (G_body computed first); the local apparel module then trains on the
  /// anchors it meets at run time, skinned with a trained skinning predictor's weights
  /// (`amt train apparel --skinning CKPT`). Unset: the ground-truth body weights. Called from the
  /// loader threads: must be thread-safe (a frozen network's forward under NoGradGuard is).
  std::function<at::Tensor(const CharacterTensors&)> anchor_body_weights;
  /// With anchor_body_weights: the share of characters that keep the ground-truth weights instead
  /// (anchor_truth_character picks them).
  double anchor_truth_share = 0.0;
};

/// True when the character `name` keeps its ground-truth anchor weights under `share` (in [0, 1]) and `seed`:
/// a hash of both below share, so the same characters are picked in every run of that seed.
bool anchor_truth_character(const std::string& name, double share, uint64_t seed);

/// Samples over one or more shards. Opening reads only attributes, clip infos and apparel masks;
/// character tensors are computed on first use and cached; frames are read per sample. get() is
/// thread-safe: each call borrows one set of DatasetReaders (one per shard) from a pool, since a
/// reader is not thread-safe.
class SampleSource {
 public:
  /// Opens the shards and lists what `options` can draw. Throws amt::Error for a missing shard,
  /// shards with different skeletons, or nothing to draw.
  SampleSource(std::vector<std::string> shards, SampleSourceOptions options);
  ~SampleSource();
  SampleSource(const SampleSource&) = delete;
  SampleSource& operator=(const SampleSource&) = delete;

  /// The shard files.
  const std::vector<std::string>& shards() const { return shards_; }
  /// The J joint names every shard uses.
  const std::vector<std::string>& joint_names() const { return joint_names_; }
  /// data_fingerprint(shards(), joint_names()).
  const std::string& fingerprint() const { return fingerprint_; }
  /// The options.
  const SampleSourceOptions& options() const { return options_; }
  /// Number of distinct samples: characters for the segmenter, windows (clip, first frame) otherwise.
  int64_t num_items() const { return num_items_; }

  /// Sample k: item hash(seed, k) mod num_items(). Identical for identical (seed, k, shards).
  TrainingSample get(int64_t k);

  /// The cached tensors of character `index` (0 .. number of characters), computed on first use.
  std::shared_ptr<const CharacterTensors> character(int index);

 private:
  struct Character;
  struct Clip;
  struct Readers;
  std::unique_ptr<Readers> borrow_readers();
  void give_back(std::unique_ptr<Readers> readers);
  std::shared_ptr<const CharacterTensors> load_character(int index, Readers& readers);

  std::vector<std::string> shards_;
  SampleSourceOptions options_;
  std::vector<std::string> joint_names_;
  std::string fingerprint_;
  std::vector<std::unique_ptr<Character>> characters_;
  std::vector<Clip> clips_;
  // Drawable items: characters (segmenter) or clips, with the cumulative count of windows before each.
  std::vector<int> items_;
  std::vector<int64_t> item_offsets_;
  int64_t num_items_ = 0;
  std::mutex pool_mutex_;
  std::vector<std::unique_ptr<Readers>> pool_;
};

// === A rank's share

/// Which samples one rank of a data-parallel run takes (train/distributed.h): at step s, rank r of W
/// ranks with `batch` samples each takes samples s*W*batch + r*batch .. s*W*batch + r*batch + batch - 1
/// of the sequence, so that the ranks take disjoint shares whose union is exactly the batch of W*batch
/// samples one process takes at step s. The default is the whole sequence (one rank).
struct SampleShare {
  int batch = 1;
  int world_size = 1;
  int rank = 0;
  /// The sequence index of the rank's j-th sample (j = step * batch + i).
  int64_t sample(int64_t j) const {
    return (j / batch) * static_cast<int64_t>(world_size) * batch + static_cast<int64_t>(rank) * batch + j % batch;
  }
};

// === Prefetching loader

/// Delivers the samples share.sample(j), j = first .. first + count - 1, of a source in order, read ahead
/// by `threads` worker threads (0: read in next() on the calling thread) at most `prefetch` samples ahead.
/// The sequence is that of source.get(share.sample(j)) whatever the threads do. The source must outlive
/// the loader.
class SampleLoader {
 public:
  /// Starts `threads` workers on the rank's samples j in [first, first + count) of `source`.
  SampleLoader(SampleSource& source, int64_t first, int64_t count, int threads = 2, int prefetch = 8,
               SampleShare share = {});
  /// Stops and joins the workers.
  ~SampleLoader();
  SampleLoader(const SampleLoader&) = delete;
  SampleLoader& operator=(const SampleLoader&) = delete;

  /// The next sample; rethrows an error a worker met reading it. Throws amt::Error past the end.
  TrainingSample next();

 private:
  void work();

  SampleSource& source_;
  SampleShare share_;
  int64_t end_;
  int prefetch_;
  std::mutex mutex_;
  std::condition_variable changed_;
  int64_t next_to_read_;
  int64_t next_to_deliver_;
  bool stopping_ = false;
  std::map<int64_t, TrainingSample> ready_;
  std::map<int64_t, std::exception_ptr> errors_;
  std::vector<std::thread> workers_;
};

}  // namespace amt
