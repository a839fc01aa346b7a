#pragma once
// The runtime tests' inputs: the micro dataset (capsule character whose pelvis capsules are apparel,
// 30-frame walks), an untrained model of its skeleton, and the ground-truth apparel mask as an
// artist's mask file, so that the untrained segmenter does not decide.
#include <filesystem>
#include <fstream>
#include <string>

#include "data_tools/formats/dataset_file.h"
#include "infer/runtime_torch.h"
#include "tests/test_support.h"
#include "tests/train/fresh_model.h"
#include "tests/train/micro_dataset.h"

namespace amt::test {

struct RuntimeFixture {
  std::filesystem::path dir;
  std::string data, model, mask;
};

/// A fresh folder `name` holding micro.h5, model/ and mask.txt.
inline RuntimeFixture make_runtime_fixture(const std::string& name) {
  RuntimeFixture f;
  f.dir = temp_dir(name);
  f.data = (f.dir / "micro.h5").string();
  write_micro_dataset(f.data);
  f.model = write_fresh_model(f.dir / "model");
  const CharacterData c = DatasetReader(f.data).read_character("capsules");
  f.mask = (f.dir / "mask.txt").string();
  std::ofstream out(f.mask);
  for (uint8_t m : c.apparel_mask) out << int(m) << "\n";
  return f;
}

/// Options animating the capsules with the clip walk0 into `out`, quietly.
inline AnimateOptions runtime_options(const RuntimeFixture& f, const std::string& out) {
  AnimateOptions o;
  o.character.spec = f.data + ":capsules";
  o.motion.spec = f.data + ":walk0";
  o.model_dir = f.model;
  o.apparel_mask = f.mask;
  o.out = out;
  o.verbose = false;
  return o;
}

}  // namespace amt::test
