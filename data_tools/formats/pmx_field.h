#pragma once
// The name of a PMX field in messages and offset tables: "bones[3].parent", "vertices[2].bones[1]". Shared by the
// reader (data_tools/formats/pmx_import.cpp) and the writer (data_tools/formats/pmx_export.h), so that a field
// the writer puts at an offset is named as the reader names it when it rejects that offset.
#include <cstdint>
#include <string>

namespace amt {

/// table[index].member[sub_index].sub_member, each part present when set; formatted only when str() is called.
struct PmxField {
  const char* table;
  int64_t index = -1;
  const char* member = nullptr;
  int64_t sub_index = -1;
  const char* sub_member = nullptr;

  PmxField(const char* table_name) : table(table_name) {}  // NOLINT: implicit, a field name reads as a string
  PmxField(const char* table_name, int64_t i, const char* member_name = nullptr, int64_t k = -1,
           const char* sub_member_name = nullptr)
      : table(table_name), index(i), member(member_name), sub_index(k), sub_member(sub_member_name) {}

  std::string str() const {
    std::string s = table;
    if (index >= 0) s += "[" + std::to_string(index) + "]";
    if (member) s += std::string(".") + member;
    if (sub_index >= 0) s += "[" + std::to_string(sub_index) + "]";
    if (sub_member) s += std::string(".") + sub_member;
    return s;
  }
};

}  // namespace amt
