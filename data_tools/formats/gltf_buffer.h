#pragma once
// Typed arrays appended to a tinygltf model's one buffer, each in a buffer view of its own on a 4-byte boundary:
// the writers of data_tools/formats (gltf_export.cpp, pmx_gltf.cpp, gltf_import.cpp's animated copy) build their
// files with it. Debian's libtinygltf, with its default options: no TINYGLTF_* option macro may be defined before
// including it.
#include <tiny_gltf.h>

#include <algorithm>
#include <limits>
#include <vector>

namespace amt {

/// Appends to `model`'s buffer 0 (made when the model has none; data already there is kept).
class GltfBuffer {
 public:
  explicit GltfBuffer(tinygltf::Model& model) : model_(model) { model_.buffers.resize(1); }

  int view(const void* bytes, size_t size, int target) {
    std::vector<unsigned char>& data = model_.buffers[0].data;
    data.resize((data.size() + 3) / 4 * 4, 0);
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = data.size();
    v.byteLength = size;
    v.target = target;
    data.insert(data.end(), static_cast<const unsigned char*>(bytes), static_cast<const unsigned char*>(bytes) + size);
    model_.bufferViews.push_back(v);
    return int(model_.bufferViews.size()) - 1;
  }

  // An accessor over `values` (count x components of C++ type T, glTF component type `component`); `bounds`
  // writes min and max.
  template <typename T>
  int accessor(const std::vector<T>& values, int component, int type, int components, int target, bool bounds) {
    tinygltf::Accessor a;
    a.bufferView = view(values.data(), values.size() * sizeof(T), target);
    a.componentType = component;
    a.type = type;
    a.count = values.size() / size_t(components);
    if (bounds) {
      a.minValues.assign(size_t(components), std::numeric_limits<double>::infinity());
      a.maxValues.assign(size_t(components), -std::numeric_limits<double>::infinity());
      for (size_t i = 0; i < values.size(); ++i) {
        double& lo = a.minValues[i % size_t(components)];
        double& hi = a.maxValues[i % size_t(components)];
        lo = std::min(lo, double(values[i]));
        hi = std::max(hi, double(values[i]));
      }
    }
    model_.accessors.push_back(a);
    return int(model_.accessors.size()) - 1;
  }

 private:
  tinygltf::Model& model_;
};

}  // namespace amt
