#include "train/samples.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <random>
#include <sstream>

#include "data_tools/builder/artist_style.h"
#include "data_tools/builder/segmenter_augmentation.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/apparel_topology.h"
#include "data_tools/geometry/error.h"
#include "data_tools/geometry/geodesic.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/segmentation_features.h"
#include "models/apparel_displacement.h"
#include "models/apparel_handles.h"
#include "models/edge_conv.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

uint64_t splitmix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

at::Tensor float_tensor(const float* data, std::vector<int64_t> shape) {
  return at::from_blob(const_cast<float*>(data), shape, at::kFloat).clone();
}

// A tensor over `m`'s storage, which it takes over (no copy): float matrices read per sample.
at::Tensor owning_tensor(MatrixX3f&& m, std::vector<int64_t> shape) {
  auto* owned = new MatrixX3f(std::move(m));
  return at::from_blob(
      owned->data(), shape, [owned](void*) { delete owned; }, at::TensorOptions().dtype(at::kFloat));
}

at::Tensor edge_tensor(const MatrixX2i& E) {
  if (E.rows() == 0) return at::zeros({0, 2}, at::kLong);
  return at::from_blob(const_cast<int32_t*>(E.data()), {E.rows(), 2}, at::kInt).to(at::kLong);
}

// (count, J, 3, 4) from count * J transforms, frame-major.
at::Tensor transforms_tensor(const Transforms& transforms, int count, int J) {
  at::Tensor out = at::empty({count, J, 3, 4}, at::kFloat);
  float* dst = out.data_ptr<float>();
  for (size_t i = 0; i < transforms.size(); ++i) std::memcpy(dst + 12 * i, transforms[i].data(), 12 * sizeof(float));
  return out;
}

// FNV-1a over bytes.
void fnv1a(uint64_t& hash, const void* data, size_t size) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) hash = (hash ^ bytes[i]) * 0x100000001B3ull;
}

}  // namespace

// === Shards

std::vector<std::string> resolve_shards(const std::vector<std::string>& inputs) {
  AMT_CHECK(!inputs.empty(), "--data: expected at least one dataset file or folder, found none");
  std::vector<std::string> shards;
  for (const std::string& input : inputs) {
    std::error_code error;
    AMT_CHECK(fs::exists(input, error), input,
              ": no such file or folder (expected a dataset shard or a folder of *.h5)");
    if (!fs::is_directory(input, error)) {
      shards.push_back(input);
      continue;
    }
    std::vector<std::string> found;
    for (const auto& entry : fs::directory_iterator(input)) {
      if (entry.is_regular_file() && entry.path().extension() == ".h5") found.push_back(entry.path().string());
    }
    AMT_CHECK(!found.empty(), input, ": no shards (expected *.h5 dataset files)");
    std::sort(found.begin(), found.end());
    shards.insert(shards.end(), found.begin(), found.end());
  }
  return shards;
}

std::string data_fingerprint(const std::vector<std::string>& shards, const std::vector<std::string>& joint_names) {
  uint64_t hash = 0xCBF29CE484222325ull;
  for (const std::string& shard : shards) {
    std::error_code error;
    const uintmax_t size = fs::file_size(shard, error);
    AMT_CHECK(!error, shard, ": no such shard (", error.message(), ")");
    const std::string name = fs::path(shard).filename().string();
    fnv1a(hash, name.data(), name.size() + 1);
    const uint64_t size64 = size;
    fnv1a(hash, &size64, sizeof(size64));
  }
  for (const std::string& joint : joint_names) fnv1a(hash, joint.data(), joint.size() + 1);
  std::ostringstream out;
  out << "fnv1a64:" << std::hex << std::setw(16) << std::setfill('0') << hash;
  return out.str();
}

// === SampleSource

struct SampleSource::Character {
  int shard = 0;
  std::string name;
  CharacterSummary summary;
  std::once_flag once;
  std::shared_ptr<const CharacterTensors> tensors;
};

struct SampleSource::Clip {
  int shard = 0;
  std::string name;
  int character = 0;
  int num_frames = 0;
  std::string split;
};

// One reader per shard, opened on first use by the thread that borrowed the set.
struct SampleSource::Readers {
  std::vector<std::unique_ptr<DatasetReader>> per_shard;
  DatasetReader& at(int shard, const std::vector<std::string>& paths) {
    if (!per_shard[shard]) per_shard[shard] = std::make_unique<DatasetReader>(paths[shard]);
    return *per_shard[shard];
  }
};

SampleSource::SampleSource(std::vector<std::string> shards, SampleSourceOptions options)
    : shards_(std::move(shards)), options_(std::move(options)) {
  AMT_CHECK(!shards_.empty(), "training data: expected at least one shard, found none");
  AMT_CHECK(options_.kind == ModuleKind::kSegmenter || options_.frames >= 1, "training data: window frames: expected ",
            ">= 1, found ", options_.frames);
  auto readers = std::make_unique<Readers>();
  readers->per_shard.resize(shards_.size());
  for (size_t s = 0; s < shards_.size(); ++s) {
    std::error_code error;
    AMT_CHECK(fs::is_regular_file(shards_[s], error), shards_[s], ": no such shard (expected an amt-dataset file)");
    DatasetReader& reader = readers->at(static_cast<int>(s), shards_);
    if (s == 0) {
      joint_names_ = reader.joint_names();
    } else {
      AMT_CHECK(reader.joint_names() == joint_names_, shards_[s], ": skeleton: expected the ", joint_names_.size(),
                " joints of ", shards_[0], ", found ", reader.joint_names().size(), " different ones");
    }
    std::map<std::string, int> index_of;
    for (const std::string& name : reader.character_names()) {
      auto c = std::make_unique<Character>();
      c->shard = static_cast<int>(s);
      c->name = name;
      c->summary = reader.character_summary(name);
      index_of[name] = static_cast<int>(characters_.size());
      characters_.push_back(std::move(c));
    }
    for (const std::string& name : reader.clip_names()) {
      const ClipInfo info = reader.clip_info(name);
      clips_.push_back({static_cast<int>(s), name, index_of.at(info.character), info.num_frames, info.split});
    }
  }
  fingerprint_ = data_fingerprint(shards_, joint_names_);

  item_offsets_.push_back(0);
  if (options_.kind == ModuleKind::kSegmenter) {
    for (size_t c = 0; c < characters_.size(); ++c) {
      if (characters_[c]->summary.split != options_.split) continue;
      items_.push_back(static_cast<int>(c));
      item_offsets_.push_back(item_offsets_.back() + 1);
    }
  } else {
    for (size_t k = 0; k < clips_.size(); ++k) {
      const Clip& clip = clips_[k];
      const CharacterSummary& summary = characters_[clip.character]->summary;
      if (clip.split != options_.split || clip.num_frames < options_.frames) continue;
      if (options_.kind == ModuleKind::kApparel && summary.num_apparel_vertices == 0) continue;
      if (options_.kind == ModuleKind::kSkinning && summary.num_apparel_vertices == summary.num_vertices) continue;
      items_.push_back(static_cast<int>(k));
      item_offsets_.push_back(item_offsets_.back() + clip.num_frames - options_.frames + 1);
    }
  }
  num_items_ = item_offsets_.back();
  const char* what = options_.kind == ModuleKind::kSegmenter  ? " characters"
                     : options_.kind == ModuleKind::kApparel  ? " clips with apparel vertices of at least "
                     : options_.kind == ModuleKind::kSkinning ? " clips with body vertices of at least "
                                                              : " clips of at least ";
  AMT_CHECK(num_items_ > 0, shards_[0], (shards_.size() > 1 ? " (and the other shards)" : ""), ": no ", options_.split,
            what, (options_.kind == ModuleKind::kSegmenter ? "" : std::to_string(options_.frames) + " frames"),
            " (needed to train the ", module_kind_name(options_.kind), " module)");
  give_back(std::move(readers));
}

SampleSource::~SampleSource() = default;

std::unique_ptr<SampleSource::Readers> SampleSource::borrow_readers() {
  std::lock_guard<std::mutex> lock(pool_mutex_);
  if (pool_.empty()) {
    auto readers = std::make_unique<Readers>();
    readers->per_shard.resize(shards_.size());
    return readers;
  }
  auto readers = std::move(pool_.back());
  pool_.pop_back();
  return readers;
}

void SampleSource::give_back(std::unique_ptr<Readers> readers) {
  std::lock_guard<std::mutex> lock(pool_mutex_);
  pool_.push_back(std::move(readers));
}

std::shared_ptr<const CharacterTensors> SampleSource::load_character(int index, Readers& readers) {
  Character& c = *characters_.at(index);
  std::call_once(c.once, [&] {
    const CharacterData data = readers.at(c.shard, shards_).read_character(c.name);
    auto t = std::make_shared<CharacterTensors>();
    t->shard = shards_[c.shard];
    t->name = c.name;
    const int64_t N = data.mesh.num_vertices(), J = data.skeleton.num_joints();
    t->V = float_tensor(data.mesh.V.data(), {N, 3});
    t->joints = float_tensor(data.skeleton.rest_joints.data(), {J, 3});
    t->edges = edge_tensor(unique_edges(data.mesh.F));
    t->apparel_mask = at::from_blob(const_cast<uint8_t*>(data.apparel_mask.data()), {N}, at::kByte).to(at::kBool);
    t->apparel_ids = at::nonzero(t->apparel_mask).flatten();
    t->body_ids = at::nonzero(t->apparel_mask.logical_not()).flatten();
    t->body_weights = float_tensor(data.body_weights.data(), {N, J});
    const LinkedTopology topology = linked_topology(data.mesh.V, data.mesh.F, data.apparel_mask);
    t->graph_edges = edge_tensor(topology.edges);
    t->body_edges = induced_edges(N, t->graph_edges, t->body_ids);
    t->apparel_edges = induced_edges(N, t->graph_edges, t->apparel_ids);
    t->apparel_neighbors = neighbor_table(t->apparel_ids.size(0), t->apparel_edges);
    if (options_.kind == ModuleKind::kSegmenter) {
      const auto features_of = [&](const TriMesh& mesh) {
        const MatrixXfR X = segmenter_input_features(options_.segmenter_inputs, mesh.V, mesh.F,
                                                     data.skeleton.rest_joints, data.skeleton.parents);
        return float_tensor(X.data(), {X.rows(), X.cols()});
      };
      t->segmenter_features = features_of(data.mesh);
      const double held = options_.segmenter_held_weight;
      if (held != 1.0) t->segmenter_weights = held_rows_weights(data.apparel_mask, data.mesh.F, held);
      if (options_.segmenter_variants) {
        const SegmenterExample e{data.mesh, data.skeleton, data.body_weights, data.apparel_mask};
        const auto add = [&](const std::string& what, const SegmenterExample& v) {
          const int64_t n = v.mesh.num_vertices();
          if (n == 0 || v.mesh.num_faces() == 0) return;  // e.g. a character that is all apparel: no bare body
          t->segmenter_variants.push_back(
              {what, float_tensor(v.mesh.V.data(), {n, 3}), features_of(v.mesh),
               at::from_blob(const_cast<uint8_t*>(v.apparel_mask.data()), {n}, at::kByte).to(at::kBool),
               held != 1.0 ? held_rows_weights(v.apparel_mask, v.mesh.F, held) : at::Tensor()});
        };
        add("bare_body", bare_body_example(e));
        // Open parts need the canonical skeleton's body (open_parts_example); other characters go
        // without, with a warning.
        try {
          add("open_parts", open_parts_example(e));
          add("bare_open_parts", open_parts_example(e, /*bare=*/true));
        } catch (const Error& error) {
          std::fprintf(stderr, "warning: %s: /characters/%s: no open-parts variant for the segmenter: %s\n",
                       shards_[c.shard].c_str(), c.name.c_str(), error.what());
        }
        if (options_.segmenter_artist_vertices >= 0) {
          ArtistStyleOptions artist;
          std::seed_seq seq{uint64_t(options_.seed), uint64_t(std::hash<std::string>{}(c.name)), uint64_t(0xa57)};
          std::mt19937_64 draw(seq);
          artist.seed = draw();
          artist.target_vertices = options_.segmenter_artist_vertices;
          try {
            const ArtistStyleCharacter r = artist_style_character(data, artist);
            add("artist_style", SegmenterExample{r.character.mesh, r.character.skeleton, r.character.body_weights,
                                                 r.character.apparel_mask});
          } catch (const Error& error) {
            std::fprintf(stderr, "warning: %s: /characters/%s: no artist-style variant for the segmenter: %s\n",
                         shards_[c.shard].c_str(), c.name.c_str(), error.what());
          }
        }
      }
    }
    if ((options_.kind == ModuleKind::kSkinning || options_.geodesics) && t->body_ids.size(0) > 0) {
      // The body mesh: body vertices and the faces whose three corners are body vertices, welded as bind welds
      // it (welded_geodesics), so that the trainer and the runtime see the same distances.
      const int64_t N_b = t->body_ids.size(0);
      const at::Tensor ids = t->body_ids.to(at::kInt).contiguous();
      const MatrixXfR G = welded_geodesics(data.mesh.V, data.mesh.F, data.skeleton.rest_joints,
                                           std::vector<int32_t>(ids.data_ptr<int32_t>(), ids.data_ptr<int32_t>() + N_b),
                                           canonical_copies(topology.weld, data.apparel_mask),
                                           shards_[c.shard] + ": /characters/" + c.name + ": body");
      t->G_body = float_tensor(G.data(), {N_b, J});
    }
    // The anchors' weights: ground truth, or what options_.anchor_body_weights gives (a trained predictor's).
    const bool predicted_anchors = options_.anchor_body_weights && t->body_ids.size(0) > 0 &&
                                   !anchor_truth_character(c.name, options_.anchor_truth_share, options_.seed);
    const at::Tensor anchor_body_weights =
        predicted_anchors ? options_.anchor_body_weights(*t) : t->body_weights.index_select(0, t->body_ids);
    t->apparel_anchor = options_.apparel_anchor;
    t->apparel_anchor_weights = apparel_anchor_weights_for(options_.apparel_anchor, t->V, t->graph_edges,
                                                           t->apparel_ids, t->body_ids, anchor_body_weights);
    t->apparel_graph = apparel_graph(t->V, t->graph_edges, t->apparel_ids, t->body_ids, t->apparel_anchor_weights,
                                     t->joints, t->apparel_neighbors, anchor_body_weights);
    if (data.rig && data.rig->response.rows() > 0 && t->apparel_ids.size(0) > 0) {
      // How lively the character's own physics is (the module's response inputs; unknown without it).
      t->apparel_graph.response =
          apparel_response(data.rig->skin_indices, data.rig->skin_weights, data.rig->response, t->apparel_ids);
    }
    t->apparel_node_ids = t->apparel_ids;
    t->apparel_node_edges = t->apparel_edges;
    if (options_.handle_spacing > 0 && t->apparel_ids.size(0) > 0) {
      t->apparel_rig =
          apparel_rig(t->V, t->graph_edges, t->apparel_ids, t->body_ids, handle_options(options_.handle_spacing));
      t->apparel_graph = handle_graph(t->apparel_graph, t->apparel_rig);
      t->apparel_node_ids = t->apparel_ids.index_select(0, t->apparel_rig.rows);
      t->apparel_node_edges = t->apparel_rig.edges;
    }
    c.tensors = std::move(t);
  });
  return c.tensors;
}

bool anchor_truth_character(const std::string& name, double share, uint64_t seed) {
  if (!(share > 0.0)) return false;
  uint64_t hash = 0xCBF29CE484222325ull;
  fnv1a(hash, &seed, sizeof(seed));
  fnv1a(hash, name.data(), name.size());
  // FNV-1a leaves its high bits nearly alike for names that differ in the last characters: mix them (the
  // finaliser of MurmurHash3's 64-bit hash) before the top 53 bits become a uniform number in [0, 1). Not
  // splitmix64 above: the shipped apparel_own_weights.ckpt was trained on the characters this finaliser picks.
  hash = (hash ^ (hash >> 33)) * 0xFF51AFD7ED558CCDull;
  hash = (hash ^ (hash >> 33)) * 0xC4CEB9FE1A85EC53ull;
  hash ^= hash >> 33;
  return double(hash >> 11) * 0x1.0p-53 < share;
}

at::Tensor held_rows_weights(const std::vector<uint8_t>& mask, const MatrixX3i& F, double weight) {
  const int N = static_cast<int>(mask.size());
  int count = 0;
  const std::vector<int32_t> part = connected_components(N, unique_edges(F), &count);
  std::vector<uint8_t> holds_apparel(static_cast<size_t>(count), 0);
  for (int i = 0; i < N; ++i) holds_apparel[static_cast<size_t>(part[size_t(i)])] |= mask[size_t(i)];
  at::Tensor w = at::ones({N}, at::kFloat);
  float* out = w.data_ptr<float>();
  for (int i = 0; i < N; ++i)
    if (!mask[size_t(i)] && holds_apparel[static_cast<size_t>(part[size_t(i)])]) out[i] = static_cast<float>(weight);
  return w;
}

std::shared_ptr<const CharacterTensors> SampleSource::character(int index) {
  AMT_CHECK(index >= 0 && index < static_cast<int>(characters_.size()), "training data: character index: expected [0, ",
            characters_.size(), "), found ", index);
  auto readers = borrow_readers();
  auto tensors = load_character(index, *readers);
  give_back(std::move(readers));
  return tensors;
}

TrainingSample SampleSource::get(int64_t k) {
  const uint64_t hash = splitmix64(options_.seed ^ splitmix64(static_cast<uint64_t>(k)));
  const int64_t r = static_cast<int64_t>(hash % static_cast<uint64_t>(num_items_));
  const size_t item = std::upper_bound(item_offsets_.begin(), item_offsets_.end(), r) - item_offsets_.begin() - 1;
  auto readers = borrow_readers();
  TrainingSample sample;
  try {
    if (options_.kind == ModuleKind::kSegmenter) {
      sample.character = load_character(items_[item], *readers);
    } else {
      const Clip& clip = clips_[items_[item]];
      sample.character = load_character(clip.character, *readers);
      sample.clip = clip.name;
      sample.first_frame = static_cast<int>(r - item_offsets_[item]);
      // A second, independent draw decides whether the window starts at the clip's first frame.
      const uint64_t start_draw = splitmix64(hash ^ 0x5bd1e995u);
      if (options_.clip_start_fraction > 0 &&
          static_cast<double>(start_draw >> 11) * 0x1.0p-53 < options_.clip_start_fraction)
        sample.first_frame = 0;
      DatasetReader& reader = readers->at(clip.shard, shards_);
      const int F = options_.frames, J = static_cast<int>(joint_names_.size());
      sample.joint_transforms = transforms_tensor(reader.read_joint_transforms(clip.name, sample.first_frame, F), F, J);
      MatrixX3f vertices = reader.read_vertices(clip.name, sample.first_frame, F);
      const int64_t N = vertices.rows() / F;
      sample.vertices = owning_tensor(std::move(vertices), {F, N, 3});
    }
  } catch (...) {
    give_back(std::move(readers));
    throw;
  }
  give_back(std::move(readers));
  return sample;
}

// === SampleLoader

SampleLoader::SampleLoader(SampleSource& source, int64_t first, int64_t count, int threads, int prefetch,
                           SampleShare share)
    : source_(source),
      share_(share),
      end_(first + count),
      prefetch_(std::max(1, prefetch)),
      next_to_read_(first),
      next_to_deliver_(first) {
  AMT_CHECK(share_.batch >= 1 && share_.world_size >= 1 && share_.rank >= 0 && share_.rank < share_.world_size,
            "training data: share: expected batch >= 1 and rank in [0, world size), found batch ", share_.batch,
            ", rank ", share_.rank, " of ", share_.world_size);
  for (int i = 0; i < threads; ++i) workers_.emplace_back([this] { work(); });
}

SampleLoader::~SampleLoader() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  for (auto& worker : workers_) worker.join();
}

void SampleLoader::work() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    changed_.wait(
        lock, [this] { return stopping_ || (next_to_read_ < end_ && next_to_read_ < next_to_deliver_ + prefetch_); });
    if (stopping_) return;
    const int64_t k = next_to_read_++;
    lock.unlock();
    TrainingSample sample;
    std::exception_ptr error;
    try {
      sample = source_.get(share_.sample(k));
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    if (error) {
      errors_[k] = error;
    } else {
      ready_[k] = std::move(sample);
    }
    changed_.notify_all();
  }
}

TrainingSample SampleLoader::next() {
  AMT_CHECK(next_to_deliver_ < end_, "training data: sample ", next_to_deliver_, ": past the loader's end ", end_);
  const int64_t k = next_to_deliver_;
  if (workers_.empty()) {
    ++next_to_deliver_;
    return source_.get(share_.sample(k));
  }
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return ready_.count(k) != 0 || errors_.count(k) != 0; });
  ++next_to_deliver_;
  changed_.notify_all();
  if (auto it = errors_.find(k); it != errors_.end()) std::rethrow_exception(it->second);
  TrainingSample sample = std::move(ready_.at(k));
  ready_.erase(k);
  return sample;
}

}  // namespace amt
