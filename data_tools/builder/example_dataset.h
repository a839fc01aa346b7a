#pragma once
// A small example dataset built from the core pieces alone: a capsule stand-in character on the
// canonical skeleton, a procedural walk, ground truth by rigid skinning. It exercises the whole
// file format end to end until the dataset builder (`amt dataset build`) produces real datasets
// with simulated apparel; it contains no apparel (every mask entry is 0).
#include <string>

#include "data_tools/formats/dataset_file.h"

namespace amt {

/// The example character "capsules": capsule_character on `skeleton` with about `vertices`
/// vertices, split "train", every vertex rigidly bound (weight 1) to the joint its part follows,
/// no apparel (all mask entries 0).
CharacterData capsule_example_character(const Skeleton& skeleton, int vertices);

/// Options of the example dataset.
struct ExampleDatasetOptions {
  int vertices = 5000;  // approximate vertex count of the character
  int frames = 60;      // frames of the walk clip
  float fps = 30.0f;
};

/// Writes the example dataset to `path` (atomically: a temporary file renamed at the end).
void write_example_dataset(const std::string& path, const ExampleDatasetOptions& options = {});

}  // namespace amt
