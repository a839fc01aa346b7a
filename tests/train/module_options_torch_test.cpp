// Network options as JSON (train/module_options.h): every field round-trips, bad fields are named.
#include "train/module_options.h"

#include <gtest/gtest.h>

#include "data_tools/error.h"
#include "tests/test_support.h"

namespace amt {
namespace {

TEST(ModuleOptions, NonDefaultValuesRoundTrip) {
  SkinningPredictorOptions s;
  s.num_joints = 7;
  s.feature_widths = {3, 5};
  s.variant = SkinningVariant::kSortByGeodesic;
  s.negative_slope = 0.1234567890123;
  s.normalize_input = false;
  SkinningPredictorOptions s2;
  options_from_json(options_to_json(s), "x.ckpt", s2);
  EXPECT_EQ(options_to_json(s2), options_to_json(s));
  EXPECT_EQ(s2.variant, SkinningVariant::kSortByGeodesic);
  EXPECT_EQ(s2.negative_slope, s.negative_slope);

  ApparelDisplacementOptions a;
  a.edge_widths = {4};
  a.velocity_scale = 3.5;
  a.root_relative = false;
  ApparelDisplacementOptions a2;
  options_from_json(options_to_json(a), "x.ckpt", a2);
  EXPECT_EQ(a2.edge_widths, a.edge_widths);
  EXPECT_EQ(a2.velocity_scale, 3.5);
  EXPECT_FALSE(a2.root_relative);

  ApparelDynamicsOptions l;
  l.edge_widths = {5, 6};
  l.inertia = 0.25;
  ApparelDynamicsOptions l2;
  options_from_json(options_to_json(l), "x.ckpt", l2);
  EXPECT_EQ(options_to_json(l2), options_to_json(l));
  EXPECT_EQ(l2.inertia, 0.25);
  // The two apparel forms are told apart by `form`, which only the local one writes.
  EXPECT_TRUE(is_local_apparel_options(options_to_json(l)));
  EXPECT_FALSE(is_local_apparel_options(options_to_json(a)));
  EXPECT_FALSE(is_local_apparel_options("not json"));
  EXPECT_EQ(test::error_of([&] { options_from_json(R"({"form":"global"})", "x.ckpt", l2); }),
            "x.ckpt: options.form: expected \"local\" (the apparel dynamics module), found \"global\"");
  // A global-form checkpoint's options are not misread as the local form.
  EXPECT_NE(test::error_of([&] { options_from_json(options_to_json(a), "old.ckpt", l2); })
                .find("old.ckpt: options."),
            std::string::npos);

  JointRefinerOptions r;
  r.hidden_widths = {9};
  r.zero_init = false;
  JointRefinerOptions r2;
  options_from_json(options_to_json(r), "x.ckpt", r2);
  EXPECT_EQ(options_to_json(r2), options_to_json(r));

  ApparelSegmenterOptions g;
  g.encoder_widths = {1, 2, 3};
  ApparelSegmenterOptions g2;
  options_from_json(options_to_json(g), "x.ckpt", g2);
  EXPECT_EQ(g2.encoder_widths, g.encoder_widths);
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
