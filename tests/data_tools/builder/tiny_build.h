#pragma once
// The tiny dataset build of the dataset builder and dataset info tests: about 1000 vertices per character, 3
// procedural clips of 10 frames, settling 0.1 s, committing every 2 clips.
#include <filesystem>

#include "data_tools/builder/dataset_builder.h"

namespace amt::test {

/// Build options of the tiny dataset of `characters` characters, written to `out`.
inline DatasetBuildOptions tiny_build_options(const std::filesystem::path& out, int characters = 2) {
  DatasetBuildOptions o;
  o.out = out.string();
  o.seed = 11;
  o.characters = characters;
  o.procedural = 3;
  o.frames = 10;
  o.vertices = 1000;
  o.settle_seconds = 0.1f;
  o.blend_seconds = 0.2f;
  o.clips_per_commit = 2;
  o.apparel.max_pieces = 2;
  return o;
}

}  // namespace amt::test
