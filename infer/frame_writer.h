#pragma once
// The runtime's outputs, written frame by frame so that memory stays flat however long the motion:
//   .glb   with OutputInfo::skin: a skinned animation (export_gltf_skinned_animation,
//   data_tools/formats/gltf_export.h):
//          the canonical skeleton's joints move the body with its skinning weights (the 4 largest per vertex),
//          and the apparel moves with handles, joints of their own under the body joints they hang from, whose
//          transforms are fitted to each computed frame (data_tools/geometry/handle_fit.h); memory is the joints'
//          transforms, 28 bytes per joint and frame. Without a skin: an animated mesh sequence (a vertex cache,
//          infer/glb_stream_writer.h), the apparel mask in use as its COLOR_0 tint (so is the skinned one's)
//   .h5    the dataset format (data_tools/formats/dataset_file.h): the character (rest mesh, canonical skeleton,
//          the apparel mask in use, skinning weights) and one clip whose `vertices` are the predictions,
//          so that `amt eval --predictions` can score it against the ground truth of the same names
//   other  a folder of OBJ files frame_0000.obj, ... (data_tools/formats/obj_io.h)
// Nothing half-written: each output is built under a temporary name ("<out>.amt-tmp", a folder for OBJ)
// and renamed onto the output by finish(); a writer destroyed before finish() removes it.
// Nothing lost: a .glb or .h5 output replaces only a regular file; an OBJ folder holds the marker
// file ".amt-output" (format amt-obj-sequence, version, frame count) and replaces only a folder that
// holds it and nothing but frame_*.obj files. The same rule recognises the temporary folder of an
// interrupted run (the marker is written first), which is replaced; any other file or folder at the
// output or its temporary is refused with a message and left alone, as are '.', '..' and folders
// that contain the current folder.
#include <memory>
#include <string>
#include <vector>

#include "data_tools/geometry/handle_fit.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/types.h"

namespace amt {

/// A skinned .glb output's rig: the body's weights over the canonical joints (#V by 4; the rows of the apparel's
/// vertices are not used), the apparel's handles, and per handle the canonical joint it hangs from (its node's
/// parent).
struct OutputSkin {
  SparseWeights body;
  HandleSkin apparel;
  std::vector<int32_t> handle_parents;
};

/// What an output needs to know besides the frames.
///   character   name, rest mesh, canonical skeleton
///   apparel_mask  #V 0/1 in use; weights #V by J rows summing to 1 (for .h5)
///   clip, motion  names of the clip and of its source motion (for .h5)
///   frames      the number of frames that will be appended (OBJ file name digits); fps their rate
struct OutputInfo {
  std::string character = "character";
  TriMesh mesh;
  Skeleton skeleton;
  std::vector<uint8_t> apparel_mask;
  MatrixXfR weights;
  std::string clip = "clip", motion = "motion";
  int frames = 0;
  float fps = 30.0f;
  /// What made the frames: the mark of predictions in a .h5 output (`amt eval --predictions` takes only marked files).
  std::string made_by = "amt animate";
  /// A .glb is a skinned animation with this rig, a vertex cache without one.
  std::shared_ptr<const OutputSkin> skin;
};

/// An output being written.
class FrameWriter {
 public:
  virtual ~FrameWriter() = default;
  /// Appends frame V (#V by 3, metres) with its joint transforms T^(t) (J transforms).
  virtual void append(const MatrixX3f& V, const Transforms& joint_transforms) = 0;
  /// Completes the output and renames it into place. Returns a description ("out/demo.glb, 12.3 MB").
  virtual std::string finish() = 0;
  /// Frames appended so far.
  virtual int num_frames() const = 0;
};

/// "glb", "h5", "vrm" or "obj" for an output path (by extension: .glb, .h5/.hdf5, .vrm, else an OBJ folder). A .vrm
/// is written by `amt animate --apparel spring-bones` from a VRM avatar (infer/runtime_torch.cpp), not by
/// open_frame_writer.
/// Throws amt::Error for .gltf (use .glb) and for .obj (name a folder for the OBJ sequence).
std::string output_kind(const std::string& path);

/// Checks that `path` can be written before any work: what is at the output and its temporaries may be
/// replaced (see above), its parent folder can be created and a probe file in it (removed again).
/// Throws amt::Error naming the path when any check fails.
void check_output_writable(const std::string& path);

/// Opens the writer of `path` (output_kind). Checks that the output can be written before any frame
/// is computed: throws amt::Error naming the path when its folder cannot be created or written.
std::unique_ptr<FrameWriter> open_frame_writer(const std::string& path, const OutputInfo& info);

}  // namespace amt
