#pragma once
// A streaming writer of the mesh-sequence GLB of data_tools/formats/gltf_export.h ("morph target per frame",
// the same layout, the same asset.extras record), for outputs too long to hold in memory: each frame's
// deltas go to a temporary data file as they come, and finish() assembles the GLB (JSON chunk, then
// the binary chunk copied from the data file) under "<path>.amt-tmp" and renames it onto the path. Memory
// is the first frame, the faces and 24 bytes of bounds per frame, whatever the frame count.
//
// Binary chunk order: frame 0 positions, indices, the apparel tint COLOR_0 (when a mask is given), the
// T - 1 delta targets in frame order, the sparse weight indices and values, the keyframe times. A writer destroyed
// before finish() removes its temporary files and leaves the path untouched.
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "data_tools/formats/atomic_file.h"
#include "data_tools/geometry/types.h"

namespace amt {

/// Writes an animated GLB mesh sequence frame by frame. Not thread-safe.
class GlbStreamWriter {
 public:
  /// Largest frame count (the sparse weights accessor addresses T (T - 1) elements with 32-bit indices).
  static constexpr int kMaxFrames = 65536;

  /// The temporary file of the frame data while `path` is written: "<path>.frames.amt-tmp".
  static std::string frames_temporary_path(const std::string& path) { return path + ".frames" + kTemporarySuffix; }

  /// Starts a sequence at `path` (.glb) over faces F (#F by 3) of `num_vertices` vertices at `fps`.
  /// Creates the parent folder and the temporary data file "<path>.frames.amt-tmp". `name` names the mesh
  /// and node, `clip` the animation; `apparel_mask` (#V entries 0/1, or empty for none) is written as
  /// the COLOR_0 tint of data_tools/formats/gltf_export.h. Throws amt::Error for bad faces, a mask of the wrong
  /// size, fps <= 0, or an unwritable path.
  GlbStreamWriter(const std::string& path, const MatrixX3i& F, int num_vertices, float fps,
                  const std::string& name = "amt_mesh", const std::string& clip = "amt_animation",
                  const std::vector<uint8_t>& apparel_mask = {});
  ~GlbStreamWriter();
  GlbStreamWriter(const GlbStreamWriter&) = delete;
  GlbStreamWriter& operator=(const GlbStreamWriter&) = delete;

  /// Appends frame V (#V by 3, metres, finite). Throws amt::Error for a wrong shape, NaN, a failed
  /// write, or more than kMaxFrames frames.
  void append(const MatrixX3f& V);

  /// Frames appended so far.
  int num_frames() const { return frames_; }

  /// Bytes of vertex data held in memory (frame 0, indices, the delta scratch); does not grow with
  /// the frame count.
  size_t buffered_bytes() const;

  /// Writes the GLB and renames it onto the path; needs at least one frame. Returns its size in bytes.
  size_t finish();

 private:
  void remove_temporaries();

  std::string path_, data_path_, name_, clip_;
  float fps_;
  int num_vertices_;
  std::vector<float> first_;  // frame 0, 3 N floats
  std::vector<unsigned char> index_bytes_;
  int index_component_ = 0;  // 5123 (UNSIGNED_SHORT) or 5125 (UNSIGNED_INT)
  size_t index_count_ = 0;
  std::vector<uint8_t> colors_;  // COLOR_0 bytes, 4 N, or empty
  int apparel_vertices_ = 0;
  std::vector<float> delta_;   // scratch for one frame's deltas
  std::vector<float> bounds_;  // 6 per target: min xyz, max xyz
  std::FILE* data_ = nullptr;
  int frames_ = 0;
  bool finished_ = false;
};

}  // namespace amt
