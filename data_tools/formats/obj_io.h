#pragma once
// Wavefront OBJ import and export (import through tinyobjloader), the joint sidecar that lets an
// unrigged OBJ character be animated, and OBJ sequence export (one file per frame).
//
// Import: every "v" line is a vertex, in file order (texture coordinates and normals are not read);
// faces of every shape (o / g groups) are merged into one triangle mesh, polygons triangulated by
// tinyobjloader. Export writes "v x y z" with 9 significant digits (%.9g: every float reads back
// bit for bit) and "f a b c" with 1-based indices. Units are the file's; amt reads them as metres.
//
// Joint sidecar, "<name>.joints.json" beside "<name>.obj":
//   {"format": "amt-joints", "version": 1, "units": "metres",
//    "joints": [{"name": "pelvis", "parent": null, "position": [0.0, 0.95, 0.0]},
//               {"name": "left_hip", "parent": "pelvis", "position": [0.09, 0.88, 0.0]}, ...]}
// "parent" is a joint name, a joint index, or null (or -1) for the single root. Joints may be listed in
// any order; the reader orders them parents first (keeping the file's order where it already is).
// "format", "version" and "units" may be left out of a hand-written file; when present they must be
// "amt-joints", 1 and "metres".
//
// Every file is written to "<path>.amt-tmp" and renamed onto the path. Errors are amt::Error with one line
// "file: field: expected X, found Y" (with the line number for OBJ vertex lines).
#include <string>
#include <vector>

#include "data_tools/geometry/mesh.h"
#include "data_tools/geometry/skeleton.h"
#include "data_tools/geometry/types.h"

namespace amt {

// === OBJ meshes

/// Reads an OBJ file into one triangle mesh (V #V by 3 in file order, F #F by 3). Throws amt::Error
/// for an unreadable file, non-numeric, NaN or infinite coordinates, missing faces or bad indices.
TriMesh read_obj(const std::string& path);

/// Writes a mesh as OBJ (a comment header, #V "v" lines, #F "f" lines). Throws amt::Error for an
/// invalid mesh (validate_mesh) or a failed write.
void write_obj(const std::string& path, const TriMesh& mesh);

/// Writes one OBJ file per frame into `folder` (created if missing): frame_0000.obj, frame_0001.obj,
/// ... (more digits when there are more than 10 000 frames), each written atomically.
///   F       #F by 3 triangles
///   frames  T >= 1 frames of #V by 3 positions
/// Returns the paths written, in frame order.
std::vector<std::string> write_obj_sequence(const std::string& folder, const MatrixX3i& F,
                                            const std::vector<MatrixX3f>& frames);

// === Joint sidecar

/// "<stem>.joints.json" beside an OBJ path ("a/hero.obj" -> "a/hero.joints.json").
std::string joints_sidecar_path(const std::string& obj_path);

/// Reads a joint sidecar into a skeleton (topological order, validate_skeleton).
Skeleton read_joints_json(const std::string& path);

/// Writes a skeleton as a joint sidecar (parents by name, the root's parent null).
void write_joints_json(const std::string& path, const Skeleton& skeleton);

/// An unrigged character: an OBJ mesh and the skeleton of its sidecar.
struct ObjCharacter {
  TriMesh mesh;
  Skeleton skeleton;
};

/// Reads "<name>.obj" and its sidecar "<name>.joints.json".
ObjCharacter read_obj_character(const std::string& obj_path);

}  // namespace amt
