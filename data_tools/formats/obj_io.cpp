#include "data_tools/formats/obj_io.h"

// tinyobjloader is Debian's libtinyobjloader (linked by data_tools/formats/CMakeLists.txt).
#include <tiny_obj_loader.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <queue>
#include <sstream>

#include "amt/version.h"
#include "data_tools/formats/atomic_file.h"
#include "data_tools/geometry/error.h"
#include "data_tools/formats/input_file.h"

namespace amt {

namespace {

std::string read_text(const std::string& path, const char* what) {
  check_input_file(path, what);
  std::ifstream in(path, std::ios::binary);
  AMT_CHECK(in.good(), path, ": file: expected ", what, " that can be read, found an error (", std::strerror(errno),
            ")");
  std::ostringstream text;
  text << in.rdbuf();
  AMT_CHECK(!in.bad(), path, ": file: expected ", what, " that can be read, found a read error");
  return text.str();
}


std::string first_line(const std::string& s) {
  const size_t end = s.find_first_of("\r\n");
  return s.substr(0, std::min<size_t>(end, 200));
}

// The lines of an OBJ text: calls visit(line_number, begin, end) for each, with the leading spaces
// and tabs skipped and the end before any '\r'.
template <typename Visit>
void for_each_line(const std::string& text, Visit&& visit) {
  size_t line_number = 0, begin = 0;
  while (begin < text.size()) {
    size_t end = text.find('\n', begin);
    if (end == std::string::npos) end = text.size();
    ++line_number;
    size_t first = begin, last = end;
    while (first < last && (text[first] == ' ' || text[first] == '\t')) ++first;
    if (last > first && text[last - 1] == '\r') --last;
    visit(line_number, first, last);
    begin = end + 1;
  }
}

// The whitespace-separated tokens of text[begin, end).
std::vector<std::string> tokens(const std::string& text, size_t begin, size_t end) {
  std::vector<std::string> out;
  size_t i = begin;
  while (i < end) {
    while (i < end && (text[i] == ' ' || text[i] == '\t')) ++i;
    size_t j = i;
    while (j < end && text[j] != ' ' && text[j] != '\t') ++j;
    if (j > i) out.push_back(text.substr(i, j - i));
    i = j;
  }
  return out;
}

bool is_keyword(const std::string& text, size_t begin, size_t end, char keyword) {
  return end - begin >= 2 && text[begin] == keyword && (text[begin + 1] == ' ' || text[begin + 1] == '\t');
}

// Checks what tinyobjloader does not: the coordinates of every "v" line (it reads a bad number as 0),
// and the vertex index of every "f" corner (it drops polygons with a bad index, with only a warning).
// Errors name the line. Returns the number of vertices.
size_t check_obj_text(const std::string& text, const std::string& path) {
  size_t vertices = 0;
  for_each_line(text, [&](size_t line, size_t begin, size_t end) {
    if (!is_keyword(text, begin, end, 'v')) return;
    const std::vector<std::string> values = tokens(text, begin + 2, end);
    for (size_t c = 0; c < 3; ++c) {
      const std::string token = c < values.size() ? values[c] : "";
      double value = 0.0;
      const char* first = token.c_str() + (token.size() > 1 && token[0] == '+' ? 1 : 0);
      const auto [ptr, ec] = std::from_chars(first, token.c_str() + token.size(), value);
      AMT_CHECK(!token.empty() && ec == std::errc() && ptr == token.c_str() + token.size() && std::isfinite(value) &&
                    std::abs(value) <= std::numeric_limits<float>::max(),
                path, ":", line, ": v: expected 3 finite numbers, found '",
                token.empty() ? std::string("nothing") : token.substr(0, 40), "' as coordinate ", c + 1);
    }
    ++vertices;
  });
  size_t above = 0;  // vertices defined above the current line (relative indices count back from it)
  for_each_line(text, [&](size_t line, size_t begin, size_t end) {
    if (is_keyword(text, begin, end, 'v')) ++above;
    if (!is_keyword(text, begin, end, 'f')) return;
    for (const std::string& corner : tokens(text, begin + 2, end)) {
      const std::string index_text = corner.substr(0, corner.find('/'));
      int64_t index = 0;
      const auto [ptr, ec] = std::from_chars(index_text.data(), index_text.data() + index_text.size(), index);
      AMT_CHECK(!index_text.empty() && ec == std::errc() && ptr == index_text.data() + index_text.size(), path, ":",
                line, ": f: expected vertex indices, found '", corner.substr(0, 40), "'");
      if (index < 0) {
        AMT_CHECK(-index <= int64_t(above), path, ":", line, ": f: expected relative vertex indices in [-", above,
                  ", -1] (", above, " vertices above the line), found ", index);
      } else {
        AMT_CHECK(index >= 1 && index <= int64_t(vertices), path, ":", line, ": f: expected vertex indices in [1, ",
                  vertices, "], found ", index);
      }
    }
  });
  return vertices;
}

// A float as the double of its shortest decimal that reads back to the same float (at most 9
// significant digits), so JSON shows 0.95, not 0.949999988079071.
double json_number(float value) {
  char text[32];
  for (int digits = 1; digits < 9; ++digits) {
    std::snprintf(text, sizeof(text), "%.*g", digits, double(value));
    if (std::strtof(text, nullptr) == value) return std::strtod(text, nullptr);
  }
  std::snprintf(text, sizeof(text), "%.9g", double(value));
  return std::strtod(text, nullptr);
}

}  // namespace

// === OBJ meshes

TriMesh read_obj(const std::string& path) {
  const std::string text = read_text(path, "an OBJ file");
  const size_t vertex_lines = check_obj_text(text, path);
  tinyobj::ObjReader reader;
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  // Parsing from memory with no material text: "mtllib" lines are not followed (materials are not read).
  const bool ok = reader.ParseFromString(text, "", config);
  AMT_CHECK(ok, path, ": OBJ: expected a valid OBJ file, found tinyobjloader error: ", first_line(reader.Error()));
  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  const size_t N = attrib.vertices.size() / 3;
  AMT_CHECK(N == vertex_lines, path, ": v: expected ", vertex_lines, " vertices (the v lines), found ", N,
            " read by tinyobjloader");
  AMT_CHECK(N > 0, path, ": v: expected at least 1 vertex, found none");
  AMT_CHECK(N <= size_t(std::numeric_limits<int32_t>::max()), path, ": v: expected fewer than 2^31 vertices, found ",
            N);
  TriMesh mesh;
  mesh.V.resize(Eigen::Index(N), 3);
  std::copy(attrib.vertices.begin(), attrib.vertices.begin() + Eigen::Index(3 * N), mesh.V.data());
  std::vector<int32_t> faces;
  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    size_t index = 0;
    for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
      const size_t corners = shape.mesh.num_face_vertices[f];
      AMT_CHECK(index + corners <= shape.mesh.indices.size(), path, ": f: expected ", corners,
                " indices for a face of shape '", shape.name, "', found ", shape.mesh.indices.size() - index);
      if (corners == 3) {
        for (size_t k = 0; k < 3; ++k) {
          const int v = shape.mesh.indices[index + k].vertex_index;
          AMT_CHECK(v >= 0 && size_t(v) < N, path, ": f: expected vertex indices in [1, ", N, "] (or -", N,
                    " to -1), found a reference to vertex ", int64_t(v) + 1, " in shape '", shape.name, "'");
          faces.push_back(v);
        }
      }
      // Faces of 1 or 2 corners (points and lines written as f) have no area: skipped.
      index += corners;
    }
  }
  AMT_CHECK(!faces.empty(), path, ": f: expected at least 1 triangle, found none");
  mesh.F.resize(Eigen::Index(faces.size() / 3), 3);
  std::copy(faces.begin(), faces.end(), mesh.F.data());
  validate_mesh(mesh, path);
  return mesh;
}

void write_obj(const std::string& path, const TriMesh& mesh) {
  validate_mesh(mesh, path);
  std::string text;
  text.reserve(size_t(mesh.num_vertices()) * 40 + size_t(mesh.num_faces()) * 24 + 128);
  char line[128];
  std::snprintf(line, sizeof(line), "# amt %s OBJ export: %d vertices, %d triangles, metres\n", AMT_VERSION,
                mesh.num_vertices(), mesh.num_faces());
  text += line;
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    std::snprintf(line, sizeof(line), "v %.9g %.9g %.9g\n", double(mesh.V(i, 0)), double(mesh.V(i, 1)),
                  double(mesh.V(i, 2)));
    text += line;
  }
  for (int f = 0; f < mesh.num_faces(); ++f) {
    std::snprintf(line, sizeof(line), "f %d %d %d\n", mesh.F(f, 0) + 1, mesh.F(f, 1) + 1, mesh.F(f, 2) + 1);
    text += line;
  }
  write_file_atomically(path, text);
}

std::vector<std::string> write_obj_sequence(const std::string& folder, const MatrixX3i& F,
                                            const std::vector<MatrixX3f>& frames) {
  AMT_CHECK(!frames.empty(), folder, ": frames: expected at least 1 frame, found none");
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  AMT_CHECK(!ec && std::filesystem::is_directory(folder), folder, ": folder: expected a folder to write frames ",
            "into, found error: ", ec ? ec.message() : "not a folder");
  const int digits = std::max(4, int(std::to_string(frames.size() - 1).size()));
  std::vector<std::string> paths;
  for (size_t k = 0; k < frames.size(); ++k) {
    std::string number = std::to_string(k);
    number.insert(0, size_t(digits) - std::min(number.size(), size_t(digits)), '0');
    const std::string path = (std::filesystem::path(folder) / ("frame_" + number + ".obj")).string();
    TriMesh mesh;
    mesh.V = frames[k];
    mesh.F = F;
    write_obj(path, mesh);
    paths.push_back(path);
  }
  return paths;
}

// === Joint sidecar

std::string joints_sidecar_path(const std::string& obj_path) {
  std::filesystem::path path(obj_path);
  return (path.parent_path() / (path.stem().string() + ".joints.json")).string();
}

Skeleton read_joints_json(const std::string& path) {
  const std::string text = read_text(path, "a joint sidecar (.joints.json)");
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    fail(path, ": JSON: expected valid JSON, found a syntax error at byte ", e.byte);
  } catch (const nlohmann::json::exception& e) {  // e.g. out_of_range: a number too large for a double
    fail(path, ": JSON: expected valid JSON, found ", first_line(e.what()));
  }
  AMT_CHECK(doc.is_object(), path, ": JSON: expected an object at the top level, found ", doc.type_name());
  if (doc.contains("format")) {
    AMT_CHECK(doc["format"] == "amt-joints", path, ": format: expected \"amt-joints\", found ", doc["format"].dump());
  }
  if (doc.contains("version")) {
    AMT_CHECK(doc["version"] == 1, path, ": version: expected 1 (the version this amt reads), found ",
              doc["version"].dump());
  }
  if (doc.contains("units")) {
    AMT_CHECK(doc["units"] == "metres", path, ": units: expected \"metres\", found ", doc["units"].dump());
  }
  AMT_CHECK(doc.contains("joints") && doc["joints"].is_array() && !doc["joints"].empty(), path,
            ": joints: expected a non-empty array, found ", doc.contains("joints") ? doc["joints"].dump() : "none");
  const nlohmann::json& joints = doc["joints"];
  const int J = int(joints.size());

  std::vector<std::string> names(static_cast<size_t>(J));
  std::map<std::string, int> index_of;
  MatrixX3f positions(J, 3);
  for (int j = 0; j < J; ++j) {
    const nlohmann::json& joint = joints[size_t(j)];
    AMT_CHECK(joint.is_object(), path, ": joints[", j, "]: expected an object, found ", joint.type_name());
    AMT_CHECK(joint.contains("name") && joint["name"].is_string() && !joint["name"].get<std::string>().empty(), path,
              ": joints[", j, "].name: expected a non-empty string, found ",
              joint.contains("name") ? joint["name"].dump() : "none");
    names[size_t(j)] = joint["name"].get<std::string>();
    AMT_CHECK(index_of.emplace(names[size_t(j)], j).second, path, ": joints[", j, "].name: expected a unique name, ",
              "found '", names[size_t(j)], "' again");
    const bool has_position =
        joint.contains("position") && joint["position"].is_array() && joint["position"].size() == 3;
    AMT_CHECK(has_position, path, ": joints[", j, "].position: expected [x, y, z], found ",
              joint.contains("position") ? joint["position"].dump() : "none");
    for (int c = 0; c < 3; ++c) {
      const nlohmann::json& value = joint["position"][size_t(c)];
      AMT_CHECK(value.is_number() && std::isfinite(value.get<double>()), path, ": joints[", j,
                "].position: expected 3 finite numbers, found ", joint["position"].dump());
      positions(j, c) = value.get<float>();
    }
  }
  std::vector<int> parent(size_t(J), -1);
  std::vector<int> roots;
  for (int j = 0; j < J; ++j) {
    const nlohmann::json& joint = joints[size_t(j)];
    const nlohmann::json p = joint.contains("parent") ? joint["parent"] : nlohmann::json();
    if (p.is_string()) {
      const auto it = index_of.find(p.get<std::string>());
      AMT_CHECK(it != index_of.end() && it->second != j, path, ": joints[", j, "].parent: expected the name of ",
                "another joint, found ", p.dump());
      parent[size_t(j)] = it->second;
    } else if (p.is_number_integer()) {
      const bool ok = p.is_number_unsigned() ? p.get<uint64_t>() < uint64_t(J) && p.get<uint64_t>() != uint64_t(j)
                                             : p.get<int64_t>() == -1;
      AMT_CHECK(ok, path, ": joints[", j, "].parent: expected a joint index in [0, ", J, ") other than ", j,
                ", or -1, found ", p.dump());
      parent[size_t(j)] = int(p.get<int64_t>());
    } else {
      AMT_CHECK(p.is_null(), path, ": joints[", j, "].parent: expected a joint name, index or null, found ", p.dump());
    }
    if (parent[size_t(j)] < 0) roots.push_back(j);
  }
  if (roots.size() != 1) {
    std::string listed;
    for (int r : roots) listed += (listed.empty() ? "'" : ", '") + names[size_t(r)] + "'";
    fail(path, ": joints: expected exactly one root joint (parent null), found ", roots.size(),
         roots.empty() ? "" : ": " + listed);
  }
  // Parents first, smallest file index first: keeps an order that already is topological.
  std::vector<std::vector<int>> children(static_cast<size_t>(J));
  for (int j = 0; j < J; ++j) {
    if (parent[size_t(j)] >= 0) children[size_t(parent[size_t(j)])].push_back(j);
  }
  std::priority_queue<int, std::vector<int>, std::greater<int>> ready;
  ready.push(roots[0]);
  std::vector<int> order;
  while (!ready.empty()) {
    const int j = ready.top();
    ready.pop();
    order.push_back(j);
    for (int c : children[size_t(j)]) ready.push(c);
  }
  if (int(order.size()) != J) {
    std::vector<bool> placed(static_cast<size_t>(J), false);
    for (int j : order) placed[size_t(j)] = true;
    const int stuck = int(std::find(placed.begin(), placed.end(), false) - placed.begin());
    fail(path, ": joints: expected a hierarchy without cycles, found a cycle through '", names[size_t(stuck)], "'");
  }
  std::vector<int> new_index(static_cast<size_t>(J));
  for (int k = 0; k < J; ++k) new_index[size_t(order[size_t(k)])] = k;
  Skeleton s;
  s.rest_joints.resize(J, 3);
  for (int k = 0; k < J; ++k) {
    const int j = order[size_t(k)];
    s.names.push_back(names[size_t(j)]);
    s.parents.push_back(parent[size_t(j)] < 0 ? -1 : new_index[size_t(parent[size_t(j)])]);
    s.rest_joints.row(k) = positions.row(j);
  }
  validate_skeleton(s, path);
  return s;
}

void write_joints_json(const std::string& path, const Skeleton& skeleton) {
  validate_skeleton(skeleton, path);
  nlohmann::ordered_json doc;
  doc["format"] = "amt-joints";
  doc["version"] = 1;
  doc["units"] = "metres";
  nlohmann::ordered_json joints = nlohmann::ordered_json::array();
  for (int j = 0; j < skeleton.num_joints(); ++j) {
    nlohmann::ordered_json joint;
    joint["name"] = skeleton.names[size_t(j)];
    const int p = skeleton.parents[size_t(j)];
    joint["parent"] = p < 0 ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(skeleton.names[size_t(p)]);
    joint["position"] = {json_number(skeleton.rest_joints(j, 0)), json_number(skeleton.rest_joints(j, 1)),
                         json_number(skeleton.rest_joints(j, 2))};
    joints.push_back(joint);
  }
  doc["joints"] = joints;
  write_file_atomically(path, doc.dump(2) + "\n");
}

ObjCharacter read_obj_character(const std::string& obj_path) {
  ObjCharacter character;
  character.mesh = read_obj(obj_path);
  const std::string sidecar = joints_sidecar_path(obj_path);
  AMT_CHECK(std::filesystem::exists(sidecar), sidecar, ": file: expected the joint sidecar of ", obj_path,
            ", found none");
  character.skeleton = read_joints_json(sidecar);
  return character;
}

}  // namespace amt
