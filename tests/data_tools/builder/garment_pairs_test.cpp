// Garment pair sets: one garment template on two bodies gives apparel of identical connectivity at other
// positions, each body simulated under the same clips, and find_garment_pairs finds both directions; the
// topology of another seed is refused.
#include "data_tools/builder/garment_pairs.h"

#include <gtest/gtest.h>

#include "data_tools/builder/body_generator.h"
#include "data_tools/garment/cloth_retarget.h"
#include "tests/data_tools/builder/tiny_build.h"
#include "tests/test_support.h"

namespace amt {
namespace {

TEST(GarmentPairs, OneTemplateDressesTwoBodiesWithTheSameConnectivity) {
  const std::filesystem::path dir = test::temp_dir("garment_pairs");
  GarmentPairOptions o;
  o.build = test::tiny_build_options(dir / "pairs.h5");
  o.build.procedural = 1;
  o.build.frames = 4;
  o.pairs = 1;
  const GarmentPairReport report = build_garment_pairs(o);
  EXPECT_EQ(report.characters, 2);
  EXPECT_EQ(report.clips, 2);
  const DatasetReader reader(o.build.out);
  ASSERT_EQ(reader.character_names(), (std::vector<std::string>{"pair-00-a", "pair-00-b"}));
  const CharacterData a = reader.read_character("pair-00-a"), b = reader.read_character("pair-00-b");
  EXPECT_EQ(a.split, "test");
  const ClothCharacter ca{"a", a.mesh, a.apparel_mask}, cb{"b", b.mesh, b.apparel_mask};
  EXPECT_NO_THROW(check_same_apparel_connectivity(ca, cb));
  EXPECT_NE(a.mesh.num_vertices(), b.mesh.num_vertices());  // different bodies
  const std::vector<GarmentPair> pairs = find_garment_pairs(reader);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].source_character, "pair-00-a");
  EXPECT_EQ(pairs[0].target_clip, "pair-00-b__" + reader.clip_info(pairs[0].source_clip).motion);
  EXPECT_EQ(pairs[1].source_character, "pair-00-b");
}

TEST(GarmentPairs, ATopologyOfAnotherGarmentIsRefused) {
  const GeneratedBody body = generate_body(sample_body_params(uint64_t(3)), 1000);
  ApparelOptions options;
  options.kinds = {ApparelKind::kCape};
  options.min_pieces = options.max_pieces = 1;
  const DressedCharacter cape = dress_character(body, 5, options);
  ApparelOptions other = options;
  other.kinds = {ApparelKind::kSleeves};
  other.topology = cape.topology;
  EXPECT_NE(test::error_of([&] { dress_character(body, 5, other); }).find("dress_character: topology: expected"),
            std::string::npos);
}

}  // namespace
}  // namespace amt
