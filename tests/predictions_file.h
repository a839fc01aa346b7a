#pragma once
// Files of predictions for the tests of `amt eval --predictions`: a dataset file marked as predictions
// (root attribute `predictions`, as amt animate writes it), so that a test can score frames it knows
// (the ground truth itself, a shifted copy) the way a user's predictions are scored.
#include <filesystem>
#include <string>
#include <system_error>

#include "data_tools/formats/dataset_file.h"

namespace amt::test {

/// Writes `to` as the dataset file `from` marked as predictions (`from` == `to` marks it in place).
/// Returns `to`.
inline std::string copy_as_predictions(const std::string& from, const std::string& to) {
  namespace fs = std::filesystem;
  std::error_code missing;
  if (!fs::equivalent(from, to, missing)) fs::copy_file(from, to, fs::copy_options::overwrite_existing);
  DatasetWriter writer = DatasetWriter::append(to);
  writer.mark_predictions("a test's copy of " + fs::path(from).filename().string());
  writer.commit();
  return to;
}

}  // namespace amt::test
