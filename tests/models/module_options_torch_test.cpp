// Network options as JSON (models/module_options.h): every field is written and read as hand-written JSON
// says, bad fields are named.
#include "models/module_options.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cstdint>
#include <vector>

#include "data_tools/geometry/error.h"
#include "tests/test_support.h"

namespace amt {
namespace {

// Each options struct with every field set away from its default, against values written out by hand
// here (not against the module's own output): options_to_json writes exactly the hand-written JSON and
// options_from_json reads it back into exactly the hand-set fields. A field that both directions
// dropped or renamed fails here.
using Json = nlohmann::json;

// options_to_json(options) is the JSON object `expected` (key order and number spelling aside).
template <typename Options>
void expect_written_as(const Options& options, const char* expected) {
  EXPECT_EQ(Json::parse(options_to_json(options)), Json::parse(expected)) << options_to_json(options);
}

TEST(ModuleOptions, NonDefaultValuesRoundTrip) {
  SkinningPredictorOptions s;
  s.num_joints = 7;
  s.feature_widths = {3, 5};
  s.attention_widths = {2};
  s.attention_row_context = false;
  s.head_encoder_widths = {6, 8};
  s.head_decoder_widths = {9};
  s.variant = SkinningVariant::kSortByGeodesic;
  s.sort_k = 2;
  s.negative_slope = 0.1234567890123;
  s.normalize_input = false;
  const char* skinning_json = R"({"num_joints": 7, "feature_widths": [3, 5], "attention_widths": [2],
      "attention_row_context": false, "head_encoder_widths": [6, 8], "head_decoder_widths": [9],
      "variant": "sort_by_geodesic", "sort_k": 2, "negative_slope": 0.1234567890123, "normalize_input": false})";
  expect_written_as(s, skinning_json);
  SkinningPredictorOptions s2;
  options_from_json(skinning_json, "x.ckpt", s2);
  EXPECT_EQ(s2.num_joints, 7);
  EXPECT_EQ(s2.feature_widths, (std::vector<int64_t>{3, 5}));
  EXPECT_EQ(s2.attention_widths, (std::vector<int64_t>{2}));
  EXPECT_FALSE(s2.attention_row_context);
  EXPECT_EQ(s2.head_encoder_widths, (std::vector<int64_t>{6, 8}));
  EXPECT_EQ(s2.head_decoder_widths, (std::vector<int64_t>{9}));
  EXPECT_EQ(s2.variant, SkinningVariant::kSortByGeodesic);
  EXPECT_EQ(s2.sort_k, 2);
  EXPECT_EQ(s2.negative_slope, 0.1234567890123);
  EXPECT_FALSE(s2.normalize_input);

  ApparelDisplacementOptions a;
  a.num_joints = 5;
  a.motion_widths = {7};
  a.motion_code = 3;
  a.edge_widths = {4};
  a.decoder_widths = {6, 2};
  a.negative_slope = 0.5;
  a.root_relative = false;
  a.velocity_scale = 3.5;
  a.output_scale = 0.25;
  a.naive_edge_conv = true;
  a.skinned_anchor = false;
  a.zero_init = false;
  const char* displacement_json = R"({"num_joints": 5, "motion_widths": [7], "motion_code": 3, "edge_widths": [4],
      "decoder_widths": [6, 2], "negative_slope": 0.5, "root_relative": false, "velocity_scale": 3.5,
      "output_scale": 0.25, "naive_edge_conv": true, "skinned_anchor": false, "zero_init": false})";
  expect_written_as(a, displacement_json);
  ApparelDisplacementOptions a2;
  options_from_json(displacement_json, "x.ckpt", a2);
  EXPECT_EQ(a2.num_joints, 5);
  EXPECT_EQ(a2.motion_widths, (std::vector<int64_t>{7}));
  EXPECT_EQ(a2.motion_code, 3);
  EXPECT_EQ(a2.edge_widths, (std::vector<int64_t>{4}));
  EXPECT_EQ(a2.decoder_widths, (std::vector<int64_t>{6, 2}));
  EXPECT_EQ(a2.negative_slope, 0.5);
  EXPECT_FALSE(a2.root_relative);
  EXPECT_EQ(a2.velocity_scale, 3.5);
  EXPECT_EQ(a2.output_scale, 0.25);
  EXPECT_TRUE(a2.naive_edge_conv);
  EXPECT_FALSE(a2.skinned_anchor);
  EXPECT_FALSE(a2.zero_init);

  ApparelDynamicsOptions l;  // `form` has one valid value, "local" (its default)
  l.num_joints = 9;
  l.anchor = "nearest";
  l.edge_widths = {5, 6};
  l.decoder_widths = {3};
  l.negative_slope = 0.125;
  l.inertia = 0.25;
  l.naive_edge_conv = true;
  l.contact = false;
  l.reach_levels = 3;
  l.handle_spacing = 0.03125;
  l.response = true;
  l.swing_reference = 0.375;
  const char* dynamics_json = R"({"form": "local", "num_joints": 9, "anchor": "nearest", "edge_widths": [5, 6],
      "decoder_widths": [3], "negative_slope": 0.125, "inertia": 0.25, "naive_edge_conv": true,
      "contact": false, "reach_levels": 3, "handle_spacing": 0.03125, "response": true, "swing_reference": 0.375})";
  expect_written_as(l, dynamics_json);
  ApparelDynamicsOptions l2;
  options_from_json(dynamics_json, "x.ckpt", l2);
  EXPECT_EQ(l2.form, "local");
  EXPECT_EQ(l2.num_joints, 9);
  EXPECT_EQ(l2.anchor, "nearest");
  EXPECT_EQ(l2.edge_widths, (std::vector<int64_t>{5, 6}));
  EXPECT_EQ(l2.decoder_widths, (std::vector<int64_t>{3}));
  EXPECT_EQ(l2.negative_slope, 0.125);
  EXPECT_EQ(l2.inertia, 0.25);
  EXPECT_TRUE(l2.naive_edge_conv);
  EXPECT_FALSE(l2.contact);
  EXPECT_EQ(l2.reach_levels, 3);
  EXPECT_EQ(l2.handle_spacing, 0.03125);
  EXPECT_TRUE(l2.response);
  EXPECT_EQ(l2.swing_reference, 0.375);
  // The two apparel forms are told apart by `form`, which only the local one writes.
  EXPECT_TRUE(is_local_apparel_options(options_to_json(l)));
  EXPECT_FALSE(is_local_apparel_options(options_to_json(a)));
  EXPECT_FALSE(is_local_apparel_options("not json"));
  EXPECT_EQ(test::error_of([&] { options_from_json(R"({"form":"global"})", "x.ckpt", l2); }),
            "x.ckpt: options.form: expected \"local\" (the apparel dynamics module), found \"global\"");
  // A global-form checkpoint's options are not misread as the local form.
  EXPECT_NE(test::error_of([&] { options_from_json(options_to_json(a), "old.ckpt", l2); }).find("old.ckpt: options."),
            std::string::npos);

  JointRefinerOptions r;
  r.hidden_widths = {9};
  r.output_scale = 0.03125;
  r.zero_init = false;
  const char* refiner_json = R"({"hidden_widths": [9], "output_scale": 0.03125, "zero_init": false})";
  expect_written_as(r, refiner_json);
  JointRefinerOptions r2;
  options_from_json(refiner_json, "x.ckpt", r2);
  EXPECT_EQ(r2.hidden_widths, (std::vector<int64_t>{9}));
  EXPECT_EQ(r2.output_scale, 0.03125);
  EXPECT_FALSE(r2.zero_init);

  ApparelSegmenterOptions g;
  g.encoder_widths = {1, 2, 3};
  g.decoder_widths = {4};
  g.negative_slope = 0.0;
  g.normalize_input = false;
  g.inputs = "positions";
  const char* segmenter_json = R"({"encoder_widths": [1, 2, 3], "decoder_widths": [4], "negative_slope": 0.0,
      "normalize_input": false, "inputs": "positions"})";
  expect_written_as(g, segmenter_json);
  ApparelSegmenterOptions g2;
  options_from_json(segmenter_json, "x.ckpt", g2);
  EXPECT_EQ(g2.encoder_widths, (std::vector<int64_t>{1, 2, 3}));
  EXPECT_EQ(g2.decoder_widths, (std::vector<int64_t>{4}));
  EXPECT_EQ(g2.negative_slope, 0.0);
  EXPECT_FALSE(g2.normalize_input);
  EXPECT_EQ(g2.inputs, "positions");
}

TEST(ModuleOptions, SegmenterOfOldCheckpointsReadsPositionsAlone) {
  // A new segmenter reads the welded shape features; a checkpoint's options (every field) written
  // before the choice existed read positions alone (the shipped segmenter of earlier rounds); a fragment
  // such as --segmenter-options keeps the default; the choice survives a round trip.
  EXPECT_EQ(ApparelSegmenterOptions{}.inputs, "welded");
  ApparelSegmenterOptions old, fragment, round;
  options_from_json(R"({"encoder_widths":[32,64,128],"decoder_widths":[64,32],"negative_slope":0.2,
      "normalize_input":true})",
                    "segmenter.ckpt", old);
  EXPECT_EQ(old.inputs, "positions");
  EXPECT_EQ(segmenter_feature_channels(old), 0);
  options_from_json(R"({"encoder_widths":[8]})", "--segmenter-options", fragment);
  EXPECT_EQ(fragment.inputs, "welded");
  EXPECT_EQ(segmenter_feature_channels(fragment), 6);
  // The shipped segmenter of this round (shape features on the mesh as given) keeps them.
  ApparelSegmenterOptions shape;
  options_from_json(R"({"encoder_widths":[32,64,128],"decoder_widths":[64,32],"negative_slope":0.2,
      "normalize_input":true,"inputs":"shape"})",
                    "segmenter.ckpt", shape);
  EXPECT_EQ(shape.inputs, "shape");
  EXPECT_EQ(segmenter_feature_channels(shape), 6);
  options_from_json(options_to_json(old), "x.ckpt", round);
  EXPECT_EQ(round.inputs, "positions");
  ApparelSegmenterOptions bad;
  try {
    options_from_json(R"({"inputs":"colours"})", "x.ckpt", bad);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "x.ckpt: options.inputs: expected \"shape\", \"welded\" or \"positions\", found \"colours\"");
  }
}

TEST(ModuleOptions, ApparelAnchorOfOldCheckpointsIsTheNearestBodyVertex) {
  // A new module anchors by attachment; a checkpoint's options (every field, "form" among them)
  // written before the anchor was a field were anchored at the nearest body vertex; a fragment such
  // as --apparel-options keeps the default.
  ApparelDynamicsOptions fresh;
  EXPECT_EQ(fresh.anchor, "attachment");
  ApparelDynamicsOptions old;
  options_from_json("{\"form\":\"local\",\"num_joints\":22,\"inertia\":0.0}", "old.ckpt", old);
  EXPECT_EQ(old.anchor, "nearest");
  ApparelDynamicsOptions fragment;
  options_from_json("{\"edge_widths\":[8]}", "--apparel-options", fragment);
  EXPECT_EQ(fragment.anchor, "attachment");
  ApparelDynamicsOptions round;
  options_from_json(options_to_json(old), "x.ckpt", round);
  EXPECT_EQ(round.anchor, "nearest");
  // Likewise the contact inputs: a new module has them, an old checkpoint's options (the shipped
  // attachment-anchored module's among them) do not, and the choice survives a round trip.
  EXPECT_TRUE(fresh.contact);
  EXPECT_FALSE(old.contact);
  ApparelDynamicsOptions attachment_old;
  options_from_json("{\"form\":\"local\",\"anchor\":\"attachment\",\"inertia\":0.6}", "old.ckpt", attachment_old);
  EXPECT_FALSE(attachment_old.contact);
  EXPECT_EQ(attachment_old.anchor, "attachment");
  EXPECT_FALSE(round.contact);
  EXPECT_TRUE(fragment.contact);
  // Reach levels: none in an old checkpoint; a value survives the round trip.
  EXPECT_EQ(attachment_old.reach_levels, 0);
  ApparelDynamicsOptions reach, reach2;
  reach.reach_levels = 6;
  options_from_json(options_to_json(reach), "x.ckpt", reach2);
  EXPECT_EQ(reach2.reach_levels, 6);
  // Handles: none (every vertex) in an old checkpoint; a spacing out of range is refused.
  EXPECT_EQ(attachment_old.handle_spacing, 0.0);
  ApparelDynamicsOptions handles;
  EXPECT_EQ(test::error_of([&] { options_from_json(R"({"form":"local","handle_spacing":-0.5})", "h.ckpt", handles); }),
            "h.ckpt: options.handle_spacing: expected 0 (every vertex) or a spacing in (0, 1] metres, found -0.5");
  ApparelDynamicsOptions bad;
  try {
    options_from_json("{\"anchor\":\"farthest\"}", "x.ckpt", bad);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "x.ckpt: options.anchor: expected \"attachment\" or \"nearest\", found \"farthest\"");
  }
}

TEST(ModuleOptions, BadFieldsAreNamed) {
  JointRefinerOptions r;
  try {
    options_from_json("{\"hidden_widths\": [1, \"a\"]}", "x.ckpt", r);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "x.ckpt: options.hidden_widths: expected an array of integers, found [1,\"a\"]");
  }
  try {
    options_from_json("{\"depth\": 3}", "x.ckpt", r);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "x.ckpt: options.depth: unknown field (written by a newer amt?)");
  }
  EXPECT_THROW(options_from_json("not json", "x.ckpt", r), Error);
}

TEST(ModuleOptions, SkinningVariantNamesAndFileStems) {
  EXPECT_EQ(parse_skinning_variant("geodesic", "--variant"), SkinningVariant::kGeodesicAttention);
  EXPECT_EQ(parse_skinning_variant("no_geodesic", "--variant"), SkinningVariant::kNoGeodesic);
  EXPECT_EQ(parse_skinning_variant("sorted", "--variant"), SkinningVariant::kSortByGeodesic);
  EXPECT_EQ(parse_skinning_variant("sort_by_geodesic", "--variant"), SkinningVariant::kSortByGeodesic);
  EXPECT_STREQ(skinning_variant_name(SkinningVariant::kNoGeodesic), "no_geodesic");
  EXPECT_EQ(skinning_file_stem(SkinningVariant::kGeodesicAttention), "skinning");
  EXPECT_EQ(skinning_file_stem(SkinningVariant::kNoGeodesic), "skinning_no_geodesic");
  EXPECT_EQ(skinning_file_stem(SkinningVariant::kSortByGeodesic), "skinning_sorted");
  try {
    parse_skinning_variant("rignet", "--variant");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "--variant: expected geodesic, no_geodesic or sorted, found 'rignet'");
  }
}

}  // namespace
}  // namespace amt
