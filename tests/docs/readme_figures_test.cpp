// The README's headline figures against the files they come from. The README's table between the markers
// "<!-- headline-figures" and "<!-- end headline-figures -->" has one figure per row:
//   | figure | value | [name](path of a metrics.json) | `key` | made by |
// The value is a number (with a unit after it; a "%" means the key holds a share, shown times 100); the key is
// a path into the JSON file: fields separated by '.', and an array element chosen by its values in brackets,
// separated by '/' (`rows[held-out characters/paper/full].pmd_a_cm`: the one row whose fields include those
// three values; `per_thread[2]`: the one element with a field equal to 2). Each figure must equal the file's
// value rounded to the digits the README shows.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using nlohmann::json;

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot be read");
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

struct Figure {
  std::string name, value, file, key;
};

// The rows of the headline table, from the README's text.
std::vector<Figure> headline_figures(const std::string& readme) {
  const auto begin = readme.find("<!-- headline-figures");
  const auto end = readme.find("<!-- end headline-figures -->");
  if (begin == std::string::npos || end == std::string::npos || end < begin)
    throw std::runtime_error("README.md: expected the headline table between <!-- headline-figures and "
                             "<!-- end headline-figures -->");
  std::vector<Figure> figures;
  std::istringstream lines(readme.substr(begin, end - begin));
  std::string line;
  std::getline(lines, line);  // the marker
  int row = 0;
  while (std::getline(lines, line)) {
    if (trim(line).empty()) continue;
    if (line.front() != '|') throw std::runtime_error("README.md: headline table: not a table row: " + line);
    ++row;
    if (row <= 2) continue;  // header and separator
    std::vector<std::string> cells;
    std::string cell;
    std::istringstream parts(line.substr(1));
    while (std::getline(parts, cell, '|')) cells.push_back(trim(cell));
    if (!cells.empty() && cells.back().empty()) cells.pop_back();
    if (cells.size() != 5)
      throw std::runtime_error("README.md: headline table: expected 5 cells, found " + std::to_string(cells.size()) +
                               " in: " + line);
    Figure f{cells[0], cells[1], "", cells[3]};
    const auto open = cells[2].find("](");
    const auto close = cells[2].rfind(')');
    if (open == std::string::npos || close == std::string::npos || close < open)
      throw std::runtime_error("README.md: headline table: expected a link to the file in: " + line);
    f.file = cells[2].substr(open + 2, close - open - 2);
    if (f.key.size() < 2 || f.key.front() != '`' || f.key.back() != '`')
      throw std::runtime_error("README.md: headline table: expected the key in backquotes in: " + line);
    f.key = f.key.substr(1, f.key.size() - 2);
    figures.push_back(f);
  }
  return figures;
}

std::string scalar_text(const json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_integer()) return std::to_string(v.get<long long>());
  if (v.is_number()) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%g", v.get<double>());
    return buffer;
  }
  return "";
}

// The value at `key` in `doc` (see the top of the file).
const json& lookup(const json& doc, const std::string& key) {
  const json* node = &doc;
  size_t i = 0;
  while (i < key.size()) {
    if (key[i] == '.') {
      ++i;
      continue;
    }
    if (key[i] == '[') {
      const auto close = key.find(']', i);
      if (close == std::string::npos) throw std::runtime_error(key + ": unclosed [");
      std::vector<std::string> wanted;
      std::istringstream parts(key.substr(i + 1, close - i - 1));
      std::string part;
      while (std::getline(parts, part, '/')) wanted.push_back(part);
      if (!node->is_array()) throw std::runtime_error(key + ": [" + key.substr(i + 1, close - i - 1) + "] on a non-array");
      const json* match = nullptr;
      int matches = 0;
      for (const auto& element : *node) {
        bool all = true;
        for (const auto& w : wanted) {
          bool found = false;
          for (const auto& field : element.items())
            if (field.value().is_primitive() && scalar_text(field.value()) == w) found = true;
          all = all && found;
        }
        if (all) {
          match = &element;
          ++matches;
        }
      }
      if (matches != 1)
        throw std::runtime_error(key + ": expected one element matching [" + key.substr(i + 1, close - i - 1) +
                                 "], found " + std::to_string(matches));
      node = match;
      i = close + 1;
      continue;
    }
    auto next = key.find_first_of(".[", i);
    if (next == std::string::npos) next = key.size();
    const std::string name = key.substr(i, next - i);
    if (!node->is_object() || !node->contains(name)) throw std::runtime_error(key + ": no field '" + name + "'");
    node = &(*node)[name];
    i = next;
  }
  return *node;
}

// Whether the README's value text shows `actual` rounded to its digits; the message says why not.
std::optional<std::string> mismatch(const std::string& shown, double actual) {
  size_t used = 0;
  const std::string number = shown.substr(0, shown.find_first_of(" %"));
  try {
    std::stod(number, &used);
  } catch (const std::exception&) {
    return "expected a number, found '" + shown + "'";
  }
  if (used != number.size()) return "expected a number, found '" + shown + "'";
  const auto dot = number.find('.');
  const int digits = dot == std::string::npos ? 0 : static_cast<int>(number.size() - dot - 1);
  const bool percent = shown.find('%') != std::string::npos;
  const double value = percent ? actual * 100.0 : actual;
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, value);
  if (number != buffer)
    return "the README shows " + shown + ", the file holds " + std::to_string(actual) + " (" + buffer +
           (percent ? " %" : "") + " at the README's digits)";
  return std::nullopt;
}

TEST(ReadmeHeadlineFigures, EveryFigureEqualsTheFileItNames) {
  const std::string root = AMT_SOURCE_DIR;
  const auto figures = headline_figures(read_text(root + "/README.md"));
  ASSERT_GE(figures.size(), 10u) << "README.md: the headline table has too few rows";
  std::map<std::string, json> files;
  for (const auto& f : figures) {
    SCOPED_TRACE(f.name + " (" + f.file + ", " + f.key + ")");
    if (!files.count(f.file)) files[f.file] = json::parse(read_text(root + "/" + f.file));
    const json& value = lookup(files[f.file], f.key);
    ASSERT_TRUE(value.is_number()) << f.key << ": not a number";
    const auto error = mismatch(f.value, value.get<double>());
    EXPECT_FALSE(error.has_value()) << "README.md, figure '" << f.name << "': " << *error;
  }
}

TEST(ReadmeHeadlineFigures, TheMainFiguresComeFromTheShippedReport) {
  const std::string root = AMT_SOURCE_DIR;
  const auto figures = headline_figures(read_text(root + "/README.md"));
  int from_report = 0;
  for (const auto& f : figures) from_report += f.file == "models/pretrained/report/metrics.json";
  EXPECT_GE(from_report, 8) << "README.md: the headline table should mostly quote models/pretrained/report/metrics.json";
}

TEST(ReadmeHeadlineFigures, AChangedFigureIsFound) {
  // The checker itself: a figure one step off in its last digit, a share shown as a percentage, a key that
  // matches two rows.
  EXPECT_FALSE(mismatch("2.09 cm", 2.0912).has_value());
  EXPECT_TRUE(mismatch("2.10 cm", 2.0912).has_value());
  EXPECT_FALSE(mismatch("0.5 %", 0.00536).has_value());
  EXPECT_TRUE(mismatch("0.6 %", 0.00536).has_value());
  EXPECT_TRUE(mismatch("fast", 1.0).has_value());
  const json doc = json::parse(R"({"rows": [{"subset": "a", "method": "x", "v": 1}, {"subset": "a", "method": "y", "v": 2}]})");
  EXPECT_EQ(lookup(doc, "rows[a/y].v").get<int>(), 2);
  EXPECT_THROW(lookup(doc, "rows[a].v"), std::runtime_error);
  EXPECT_THROW(lookup(doc, "rows[a/z].v"), std::runtime_error);
}

}  // namespace
