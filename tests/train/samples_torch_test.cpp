// Training samples (train/samples.h): shard resolution, missing shards, per-character tensors, and a
// sample sequence that depends only on (seed, k), not on the loader threads.
#include "train/samples.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <random>
#include <string>

#include "data_tools/builder/artist_style.h"
#include "data_tools/builder/dataset_builder.h"
#include "data_tools/formats/dataset_file.h"
#include "data_tools/geometry/error.h"
#include "micro_dataset.h"
#include "tests/data_tools/builder/tiny_build.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

// The micro dataset, written once per test program.
const std::string& micro_dataset() {
  static const std::string path = [] {
    const std::string p = test::test_directory("amt_samples_test") + "/micro.h5";
    test::write_micro_dataset(p);
    return p;
  }();
  return path;
}

TEST(Samples, ResolveShardsListsFolderAndRejectsMissing) {
  const std::string shard = micro_dataset();
  const std::string folder = fs::path(shard).parent_path().string();
  EXPECT_EQ(resolve_shards({folder}), std::vector<std::string>{shard});
  EXPECT_EQ(resolve_shards({shard}), std::vector<std::string>{shard});
  try {
    resolve_shards({shard, folder + "/missing.h5"});
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              folder + "/missing.h5: no such file or folder (expected a dataset shard or a folder of *.h5)");
  }
  const std::string empty = test::test_directory("amt_samples_test_empty");
  EXPECT_THROW(resolve_shards({empty}), Error);
  SampleSourceOptions options;
  EXPECT_THROW(SampleSource({folder + "/missing.h5"}, options), Error);
}

TEST(Samples, FingerprintDependsOnFilesAndJoints) {
  const std::string a = data_fingerprint({micro_dataset()}, {"x", "y"});
  EXPECT_EQ(a.rfind("fnv1a64:", 0), 0u);
  EXPECT_EQ(a.size(), 8u + 16u);
  EXPECT_EQ(a, data_fingerprint({micro_dataset()}, {"x", "y"}));
  EXPECT_NE(a, data_fingerprint({micro_dataset()}, {"x", "z"}));
}

TEST(Samples, CharacterTensorsAreConsistent) {
  test::use_one_thread();
  SampleSourceOptions options;
  options.kind = ModuleKind::kSkinning;
  options.frames = 4;
  SampleSource source({micro_dataset()}, options);
  const auto c = source.character(0);
  const int64_t N = c->V.size(0), N_a = c->apparel_ids.size(0), N_b = c->body_ids.size(0);
  EXPECT_GT(N_a, 0);
  EXPECT_EQ(N_a + N_b, N);
  EXPECT_EQ(c->joints.sizes(), (at::IntArrayRef{22, 3}));
  EXPECT_EQ(c->G_body.sizes(), (at::IntArrayRef{N_b, 22}));
  EXPECT_TRUE(at::isfinite(c->G_body).all().item<bool>());
  EXPECT_EQ(c->apparel_neighbors.size(0), N_a);
  EXPECT_LT(c->body_edges.max().item<int64_t>(), N_b);
  EXPECT_LT(c->apparel_edges.max().item<int64_t>(), N_a);
  EXPECT_EQ(source.character(0).get(), c.get());  // cached

  const TrainingSample s = source.get(7);
  EXPECT_EQ(s.joint_transforms.sizes(), (at::IntArrayRef{4, 22, 3, 4}));
  EXPECT_EQ(s.vertices.sizes(), (at::IntArrayRef{4, N, 3}));
  EXPECT_EQ(source.num_items(), 2 * (30 - 4 + 1));
}

TEST(Samples, AnchorBodyWeightsSkinTheAnchorsAndBuildTheGraph) {
  test::use_one_thread();
  SampleSourceOptions options;
  options.kind = ModuleKind::kApparel;
  options.frames = 4;
  options.apparel_anchor = "attachment";
  SampleSource truth({micro_dataset()}, options);
  const auto gt = truth.character(0);
  // Weights that put every body vertex on joint 3 (a stand-in for a predictor's), given G_body.
  bool had_geodesics = false;
  options.geodesics = true;
  options.anchor_body_weights = [&](const CharacterTensors& c) {
    had_geodesics = c.G_body.defined() && c.G_body.size(0) == c.body_ids.size(0);
    at::Tensor W = at::zeros({c.body_ids.size(0), c.joints.size(0)});
    W.select(1, 3).fill_(1.0f);
    return W;
  };
  SampleSource predicted({micro_dataset()}, options);
  const auto c = predicted.character(0);
  EXPECT_TRUE(had_geodesics);
  const int64_t N_a = c->apparel_ids.size(0);
  ASSERT_GT(N_a, 0);
  at::Tensor expected = at::zeros({N_a, 22});
  expected.select(1, 3).fill_(1.0f);
  EXPECT_TRUE(at::equal(c->apparel_anchor_weights, expected));
  EXPECT_TRUE(at::equal(c->apparel_graph.frame_joints, at::full({N_a}, 3, at::kLong)));
  EXPECT_TRUE(at::equal(c->apparel_graph.contact_weights, expected));
  EXPECT_FALSE(at::equal(gt->apparel_anchor_weights, expected));  // the ground truth's differ
  EXPECT_TRUE(at::equal(c->body_weights, gt->body_weights));      // the training targets' weights are untouched

  // With every character on the ground truth's anchors (share 1) the predictor is not asked.
  options.anchor_truth_share = 1.0;
  had_geodesics = false;
  SampleSource mixed({micro_dataset()}, options);
  EXPECT_TRUE(at::equal(mixed.character(0)->apparel_anchor_weights, gt->apparel_anchor_weights));
  EXPECT_FALSE(had_geodesics);
}

// The characters that keep ground-truth anchors: none at share 0, all at 1, about the share between, the same
// for the same seed and others for another.
TEST(Samples, AnchorTruthShareIsAFixedSubsetOfTheCharacters) {
  int half = 0, other_seed_differs = 0;
  for (int k = 0; k < 400; ++k) {
    const std::string name = "character-" + std::to_string(k);
    EXPECT_FALSE(anchor_truth_character(name, 0.0, 1));
    EXPECT_TRUE(anchor_truth_character(name, 1.0, 1));
    const bool picked = anchor_truth_character(name, 0.5, 1);
    EXPECT_EQ(picked, anchor_truth_character(name, 0.5, 1));
    EXPECT_TRUE(!picked || anchor_truth_character(name, 0.75, 1));  // a larger share keeps the smaller's
    half += picked;
    other_seed_differs += picked != anchor_truth_character(name, 0.5, 2);
  }
  EXPECT_GT(half, 160);
  EXPECT_LT(half, 240);
  EXPECT_GT(other_seed_differs, 120);
}

TEST(Samples, SequenceDependsOnSeedAndIndexOnly) {
  SampleSourceOptions options;
  options.kind = ModuleKind::kApparel;
  options.seed = 11;
  SampleSource a({micro_dataset()}, options), b({micro_dataset()}, options);
  SampleLoader threaded(a, 5, 12, /*threads=*/3, /*prefetch=*/4);
  SampleLoader inline_loader(b, 5, 12, /*threads=*/0);
  for (int k = 5; k < 17; ++k) {
    const TrainingSample x = threaded.next(), y = inline_loader.next();
    EXPECT_EQ(x.clip, y.clip);
    EXPECT_EQ(x.first_frame, y.first_frame);
    EXPECT_TRUE(at::equal(x.vertices, y.vertices));
    EXPECT_TRUE(at::equal(x.joint_transforms, y.joint_transforms));
  }
  EXPECT_THROW(threaded.next(), Error);
  options.seed = 12;
  SampleSource c({micro_dataset()}, options);
  int differ = 0;
  for (int k = 0; k < 8; ++k) differ += a.get(k).first_frame != c.get(k).first_frame || a.get(k).clip != c.get(k).clip;
  EXPECT_GT(differ, 0);
}

// The segmenter's held rows: the body vertices of the parts that also hold apparel (where a piece hangs), not the
// body's own part, nor a part that is apparel alone.
TEST(Samples, HeldRowsAreTheBodyVerticesOfPartsThatHoldApparel) {
  MatrixX3i F(4, 3);
  F << 0, 1, 2,          // the body: body vertices only
      3, 4, 5,           // a piece: 3 is held (body), 4-6 hang
      4, 5, 6, 7, 8, 9;  // a piece of apparel alone
  const std::vector<uint8_t> mask = {0, 0, 0, 0, 1, 1, 1, 1, 1, 1};
  const at::Tensor w = held_rows_weights(mask, F, 5.0);
  EXPECT_TRUE(at::equal(w, at::tensor({1.0f, 1.0f, 1.0f, 5.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f}))) << w;
}

// The segmenter's artist-style variant: made only when asked for, the character remade by artist_style_character
// with the sample source's seed (its own vertices, features and mask, rows of one length), and the same remake on
// every load.
TEST(Samples, TheSegmentersArtistStyleVariantIsTheRemakeOfTheCharacter) {
  test::use_one_thread();
  const std::string dir = test::test_directory("amt_samples_artist_style");
  build_dataset(test::tiny_build_options(dir, 1));  // a generated, dressed character (the capsules have no head)
  const std::string shard = dir + "/character-0000.h5";
  SampleSourceOptions options;
  options.kind = ModuleKind::kSegmenter;
  options.frames = 1;
  options.segmenter_inputs = "welded";
  options.segmenter_variants = true;
  const auto variant = [](const CharacterTensors& c) -> const CharacterTensors::SegmenterVariant* {
    for (const auto& v : c.segmenter_variants)
      if (v.what == "artist_style") return &v;
    return nullptr;
  };
  {
    SampleSource plain({shard}, options);
    EXPECT_EQ(variant(*plain.character(0)), nullptr);  // not asked for
  }
  options.segmenter_artist_vertices = 0;
  SampleSource source({shard}, options);
  const auto c = source.character(0);
  const CharacterTensors::SegmenterVariant* v = variant(*c);
  ASSERT_NE(v, nullptr);
  const int64_t N = v->V.size(0);
  EXPECT_GT(N, c->V.size(0));  // UV seams split into coincident copies, double-sided panels
  EXPECT_EQ(v->features.size(0), N);
  EXPECT_EQ(v->apparel_mask.size(0), N);
  // The remake's mask is the source's carried through its map.
  CharacterData data = DatasetReader(shard).read_character(c->name);
  ArtistStyleOptions artist;
  std::seed_seq seq{uint64_t(options.seed), uint64_t(std::hash<std::string>{}(c->name)), uint64_t(0xa57)};
  std::mt19937_64 draw(seq);
  artist.seed = draw();
  artist.target_vertices = 0;
  const ArtistStyleCharacter remake = artist_style_character(data, artist);
  ASSERT_EQ(remake.character.mesh.num_vertices(), N);
  for (int64_t i = 0; i < N; ++i)
    ASSERT_EQ(v->apparel_mask[i].item<bool>(), remake.character.apparel_mask[size_t(i)] != 0) << "vertex " << i;
  const at::Tensor remade =
      at::from_blob(const_cast<float*>(remake.character.mesh.V.data()), {N, 3}, at::kFloat).clone();
  EXPECT_TRUE(at::equal(v->V, remade));
  SampleSource again({shard}, options);
  EXPECT_TRUE(at::equal(variant(*again.character(0))->V, v->V));
}

}  // namespace
}  // namespace amt
