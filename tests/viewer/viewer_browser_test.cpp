// The web viewer (issue 16) end to end: `amt animate --html` writes a viewer folder, `amt view` serves
// it (or GLB files) on 127.0.0.1, and headless Chromium, driven by viewer/check_page.mjs through
// playwright-core, must load the animation, report its frames and meshes with no error and draw a
// screenshot that is not blank; a broken GLB must be reported by the page as a failure; a skinned
// animation must play frame for frame as amt's linear blend skinning of it. When Chromium cannot start,
// the browser tests skip and say why (check_page.mjs exits 77).
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "data_tools/formats/gltf_export.h"
#include "data_tools/formats/viewer_folder.h"
#include "data_tools/geometry/lbs.h"
#include "data_tools/geometry/motion.h"
#include "data_tools/geometry/procedural_motion.h"
#include "data_tools/geometry/shapes.h"
#include "data_tools/geometry/skeleton.h"
#include "tests/test_support.h"

namespace amt {
namespace {

namespace fs = std::filesystem;

const fs::path kRepository = fs::path(AMT_ASSET_DIR).parent_path();

std::string quoted(const std::string& s) {
  std::string out = "'";
  for (const char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string amt_command(const std::vector<std::string>& args) {
  std::string command = quoted(AMT_BINARY);
  for (const std::string& a : args) command += " " + quoted(a);
  return command;
}

// `amt view ARGS --port 0` running in a child process; the URL it printed. Stopped with SIGTERM.
class ViewServer {
 public:
  explicit ViewServer(const std::vector<std::string>& args) {
    int out[2];
    if (pipe(out) != 0) return;
    pid_ = fork();
    if (pid_ == 0) {
      dup2(out[1], STDOUT_FILENO);
      close(out[0]);
      close(out[1]);
      std::vector<std::string> all = {AMT_BINARY, "view"};
      all.insert(all.end(), args.begin(), args.end());
      all.insert(all.end(), {"--port", "0"});
      std::vector<char*> argv;
      for (std::string& a : all) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(AMT_BINARY, argv.data());
      _exit(127);
    }
    close(out[1]);
    // The first line: "amt view: serving ... at http://127.0.0.1:PORT/ (Ctrl-C stops)".
    std::string line;
    pollfd fd{out[0], POLLIN, 0};
    char c = 0;
    while (line.find('\n') == std::string::npos && poll(&fd, 1, 30000) > 0 && read(out[0], &c, 1) == 1) line += c;
    close(out[0]);
    const size_t at = line.find("http://");
    if (at != std::string::npos) url_ = line.substr(at, line.find(' ', at) - at);
    printed_ = line;
  }
  ~ViewServer() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
  }
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;
  const std::string& url() const { return url_; }
  const std::string& printed() const { return printed_; }

 private:
  pid_t pid_ = -1;
  std::string url_, printed_;
};

// A viewer folder of a generated character (seed 7, 2000 vertices) walking for 8 frames.
fs::path write_animate_folder(const fs::path& d) {
  const test::CommandResult r = test::run_command(amt_command(
      {"animate", "--character", "generated:7:2000", "--motion", std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_01.bvh",
       "--frames", "8", "--html", d.string(), "--bind", "none", "--threads", "1", "--quiet"}));
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("open it with amt view " + d.string()), std::string::npos) << r.out;
  return d;
}

// The JSON chunk of a GLB file.
nlohmann::json glb_json(const fs::path& path) {
  const std::string glb = test::read_file_bytes(path);
  uint32_t json_length = 0;
  if (glb.size() >= 20) std::memcpy(&json_length, glb.data() + 12, 4);
  return nlohmann::json::parse(glb.substr(20, json_length));
}

// Runs viewer/check_page.mjs on `urls` (shell words) with `args`; status 77: Chromium cannot start.
test::CommandResult check_page(const std::string& urls, const std::string& args) {
  return test::run_command("node " + quoted((kRepository / "viewer" / "check_page.mjs").string()) + " " + urls + " " +
                           args);
}

// check_page exits with 77 when Chromium cannot start on this machine. The test is skipped then, unless
// AMT_REQUIRE_BROWSER is set (.ci/run sets it): on the CI machine a browser that does not start is a failure.
void skip_or_fail_without_chromium(const test::CommandResult& r, bool& skipped) {
  skipped = r.status == 77;
  if (!skipped) return;
  const char* required = std::getenv("AMT_REQUIRE_BROWSER");
  if (required != nullptr && std::string(required) != "" && std::string(required) != "0") {
    ADD_FAILURE() << "Chromium did not start and AMT_REQUIRE_BROWSER is set: " << r.out << r.err;
  }
}

bool browser_tools_installed() {
  if (std::system("node --version > /dev/null 2>&1") != 0) {
    ADD_FAILURE() << "Node.js (node) is not installed, so the browser test cannot run: run scripts/setup.sh";
    return false;
  }
  if (!fs::exists(kRepository / "viewer" / "node_modules" / "playwright-core" / "package.json")) {
    ADD_FAILURE() << "playwright-core is not installed in viewer/node_modules: run scripts/setup.sh (npm ci in viewer)";
    return false;
  }
  return true;
}

// One animation, three looks at it: the folder's files, the folder in Chromium, and GLB files with a
// ground truth (a copy of the skinning sequence) in Chromium, with the PMD_a readout.
TEST(ViewerBrowser, AnimateHtmlFolderAndGlbFilesPlayInChromium) {
  const fs::path dir = write_animate_folder(test::temp_dir("viewer_folder") / "walk");
  for (const char* name : {"index.html", "viewer.js", "viewer.json", "prediction.glb", "skinning.glb",
                           "three/build/three.module.js", "three/examples/jsm/loaders/GLTFLoader.js", "three/LICENSE"})
    EXPECT_TRUE(fs::is_regular_file(dir / name)) << name;
  const nlohmann::json manifest = nlohmann::json::parse(test::read_file_bytes(dir / "viewer.json"));
  EXPECT_EQ(manifest["format"], "amt-viewer");
  EXPECT_EQ(manifest["version"], 1);
  ASSERT_EQ(manifest["groups"].size(), 1u);
  EXPECT_EQ(manifest["groups"][0]["items"][0]["file"], "prediction.glb");
  EXPECT_EQ(manifest["groups"][0]["items"][1]["role"], "skinning");
  // The apparel mask travels in the GLB: COLOR_0 and the count in asset.extras.
  const nlohmann::json gltf = glb_json(dir / "prediction.glb");
  EXPECT_TRUE(gltf["meshes"][0]["primitives"][0]["attributes"].contains("COLOR_0"));
  EXPECT_GT(gltf["asset"]["extras"]["apparel_vertices"].get<int>(), 0);
  EXPECT_EQ(gltf["meshes"][0]["weights"].size(), 7u);  // 8 frames: 7 morph targets
  test::expect_valid_gltf(dir / "skinning.glb");

  if (!browser_tools_installed()) return;
  // The folder as amt view serves it, and the GLBs with a ground truth (a copy of the skinning sequence).
  const ViewServer folder({dir.string()});
  ASSERT_FALSE(folder.url().empty()) << "amt view printed: " << folder.printed();
  fs::copy_file(dir / "skinning.glb", dir.parent_path() / "ground_truth.glb");
  const ViewServer files({(dir / "prediction.glb").string(), (dir.parent_path() / "ground_truth.glb").string()});
  ASSERT_FALSE(files.url().empty()) << "amt view printed: " << files.printed();
  const fs::path shot = dir.parent_path() / "screenshot.png";
  const test::CommandResult r = check_page(quoted(folder.url()) + " " + quoted(files.url()),
                                           "--meshes 2 --apparel --screenshot " + quoted(shot.string()));
  bool skipped = false;
  skip_or_fail_without_chromium(r, skipped);
  if (skipped) GTEST_SKIP() << r.out;
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("  prediction.glb (prediction): 8 frames, "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  skinning.glb (skinning): 8 frames"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  files/1/ground_truth.glb (ground_truth): 8 frames"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("PMD_a at frame"), std::string::npos) << r.out;
  EXPECT_GT(fs::file_size(shot), 1000u);
}

// The test fails when a GLB does not load: a file cut in half (its header is right, so amt view
// serves it; its chunks are not) fails the checks, and the page's report names it.
TEST(ViewerBrowser, ABrokenGlbIsReportedAsAFailure) {
  const fs::path dir = test::temp_dir("viewer_broken");
  const TriMesh sphere = uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 12, 8);
  std::vector<MatrixX3f> frames = {sphere.V, sphere.V * 1.1f, sphere.V * 1.2f};
  GltfExportOptions options;
  options.apparel_mask.assign(size_t(sphere.num_vertices()), 1);
  export_gltf_mesh_sequence((dir / "sphere.glb").string(), sphere.F, frames, 30.0f, options);
  const std::string glb = test::read_file_bytes(dir / "sphere.glb");
  std::ofstream(dir / "broken.glb", std::ios::binary) << glb.substr(0, glb.size() / 2);
  if (!browser_tools_installed()) return;
  const ViewServer server({(dir / "broken.glb").string()});
  ASSERT_FALSE(server.url().empty()) << "amt view printed: " << server.printed();
  const test::CommandResult r = check_page(server.url(), "--meshes 1");
  bool skipped = false;
  skip_or_fail_without_chromium(r, skipped);
  if (skipped) GTEST_SKIP() << r.out;
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_NE(r.err.find("check_page: FAILED: " + server.url() + ": expected status ready, found error"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.out.find("  error: files/0/broken.glb: cannot load: "), std::string::npos) << r.out;
}

// A character animated the way `amt animate` writes it by default: capsules on the canonical skeleton (each
// vertex 0.7 on its bone's joint, 0.3 on that joint's parent) and a cape on two apparel handles (children of
// spine3 and of the pelvis, swinging and drifting by their own rotations and translations), walking for 12
// frames at 25 fps. `frames` receives amt's linear blend skinning of every frame, `mask` the cape.
struct SkinnedWalk {
  TriMesh mesh;
  Skeleton skeleton;
  SparseWeights weights;
  NodeAnimation animation;
  std::vector<MatrixX3f> frames;
  std::vector<uint8_t> mask;
};
SkinnedWalk skinned_walk() {
  SkinnedWalk w;
  w.skeleton = canonical_skeleton();
  std::vector<int32_t> joint_of_vertex;
  const TriMesh body = capsule_character(w.skeleton.rest_joints, w.skeleton.parents, 1500, &joint_of_vertex);
  constexpr int kColumns = 9, kRows = 11;
  TriMesh cape = grid(kColumns, kRows, 0.06f);  // 0.48 m wide, 0.6 m long, from 1.40 m down, behind the back
  for (int i = 0; i < cape.num_vertices(); ++i) {
    cape.V.row(i) << cape.V(i, 0) - 0.24f, 1.40f - cape.V(i, 1), -0.16f;
  }
  w.mesh = merge_meshes({body, cape});
  const int J = kCanonicalJointCount, N = w.mesh.num_vertices(), body_vertices = body.num_vertices();
  w.skeleton.names.insert(w.skeleton.names.end(), {"apparel_handle_0000", "apparel_handle_0001"});
  w.skeleton.parents.insert(w.skeleton.parents.end(), {kSpine3, kPelvis});
  w.skeleton.rest_joints.conservativeResize(J + 2, 3);
  w.skeleton.rest_joints.row(J) << 0.0f, 1.40f, -0.16f;
  w.skeleton.rest_joints.row(J + 1) << 0.0f, 1.0f, -0.16f;
  w.weights.indices.setZero(N, kMaxInfluences);
  w.weights.weights.setZero(N, kMaxInfluences);
  w.mask.assign(size_t(N), 0);
  for (int i = 0; i < N; ++i) {
    if (i < body_vertices) {
      const int j = joint_of_vertex[size_t(i)], parent = w.skeleton.parents[size_t(j)];
      w.weights.indices.row(i) << j, std::max(parent, 0), 0, 0;
      w.weights.weights.row(i) << (parent < 0 ? 1.0f : 0.7f), (parent < 0 ? 0.0f : 0.3f), 0.0f, 0.0f;
    } else {
      const float down = float((i - body_vertices) / kColumns) / float(kRows - 1);
      w.weights.indices.row(i) << J, J + 1, kSpine3, 0;
      w.weights.weights.row(i) << 0.8f * (1.0f - down), 0.8f * down, 0.2f, 0.0f;
      w.mask[size_t(i)] = 1;
    }
  }
  const Skeleton body_skeleton = canonical_skeleton();
  const Motion walk = walk_motion(12, 25.0f);
  w.animation.fps = walk.fps;
  w.animation.translated.assign(size_t(J + 2), 0);
  w.animation.translated[0] = w.animation.translated[size_t(J)] = w.animation.translated[size_t(J + 1)] = 1;
  for (int t = 0; t < walk.num_frames(); ++t) {
    Transforms T = forward_kinematics(body_skeleton, walk, t);
    for (int h = 0; h < 2; ++h) {  // the handles: a swing about x and a drift that their parents do not make
      const int p = w.skeleton.parents[size_t(J + h)];
      const Eigen::Matrix3f R = T[size_t(p)].leftCols<3>();
      const float phase = 0.6f * float(t) + float(h);
      const Eigen::Vector3f offset = (w.skeleton.rest_joints.row(J + h) - w.skeleton.rest_joints.row(p)).transpose() +
                                     Eigen::Vector3f(0.0f, 0.02f * std::sin(phase), -0.05f * std::sin(phase));
      const Eigen::Matrix3f swing =
          Eigen::AngleAxisf(0.5f * std::sin(phase), Eigen::Vector3f::UnitX()).toRotationMatrix();
      T.push_back(make_transform(R * swing, apply(T[size_t(p)], offset)));
    }
    append_node_frame(w.skeleton, T, w.animation);
    MatrixX3f V;
    linear_blend_skinning(w.mesh.V, w.weights, skinning_matrices(w.skeleton, T), V);
    w.frames.push_back(V);
  }
  return w;
}

// A skinned-animation GLB (export_gltf_skinned_animation) beside the mesh sequence of amt's linear blend skinning
// of it, as ground truth, in a viewer folder: the page plays the skinned file at 12 frames and 25 fps with its
// apparel tint, and its readout against the sequence (PMD over every vertex, the sequence has no mask) is below
// 1e-4 m at every frame and at the frames the page is opened on, as are the boxes: the page skins as amt does.
// Showing the rest pose instead would read 2 cm or more at those frames (checked on the frames themselves).
TEST(ViewerBrowser, ASkinnedAnimationPlaysFrameForFrameAsAmtSkinsIt) {
  const fs::path dir = test::temp_dir("viewer_skinned") / "viewer";
  const SkinnedWalk w = skinned_walk();
  GltfExportOptions options;
  options.apparel_mask = w.mask;
  write_viewer_folder(dir.string(), (kRepository / "viewer").string(),
                      {"skinned walk",
                       {{"walk",
                         {{"skinned.glb", "skinned animation", "prediction"},
                          {"ground_truth.glb", "linear blend skinning", "ground_truth"}}}}});
  export_gltf_skinned_animation((dir / "skinned.glb").string(), w.mesh, w.skeleton, w.weights, w.animation, options);
  export_gltf_mesh_sequence((dir / "ground_truth.glb").string(), w.mesh.F, w.frames, w.animation.fps);
  test::expect_valid_gltf(dir / "skinned.glb");
  EXPECT_EQ(glb_json(dir / "skinned.glb")["asset"]["extras"]["amt_format"], "skinned-animation");
  const std::vector<int> opened = {0, 5, 11};
  for (const int k : opened) {
    const float from_rest = (w.frames[size_t(k)] - w.mesh.V).rowwise().norm().mean();
    EXPECT_GT(from_rest, 0.02f) << "frame " << k << " is too close to the rest pose to tell it from the skin";
  }

  if (!browser_tools_installed()) return;
  const ViewServer server({dir.string()});
  ASSERT_FALSE(server.url().empty()) << "amt view printed: " << server.printed();
  std::string urls;
  for (const int k : opened) urls += quoted(server.url() + "?paused=1&frame=" + std::to_string(k)) + " ";
  const fs::path report_path = dir.parent_path() / "reports.json";
  const test::CommandResult r = check_page(urls, "--meshes 2 --apparel --report " + quoted(report_path.string()));
  bool skipped = false;
  skip_or_fail_without_chromium(r, skipped);
  if (skipped) GTEST_SKIP() << r.out;
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  const long apparel = long(std::count(w.mask.begin(), w.mask.end(), 1));
  EXPECT_NE(r.out.find("  skinned.glb (prediction): 12 frames, " + std::to_string(w.mesh.num_vertices()) +
                       " vertices, " + std::to_string(apparel) + " apparel, 25 fps, skinned-animation"),
            std::string::npos)
      << r.out;
  const nlohmann::json reports = nlohmann::json::parse(test::read_file_bytes(report_path));
  ASSERT_EQ(reports.size(), opened.size()) << r.out;
  for (size_t p = 0; p < opened.size(); ++p) {
    const nlohmann::json& report = reports[p];
    SCOPED_TRACE("page opened at frame " + std::to_string(opened[p]));
    EXPECT_EQ(report["status"], "ready") << report["errors"];
    EXPECT_EQ(report["errors"].size(), 0u) << report["errors"];
    EXPECT_EQ(report["frame"], opened[p]);
    EXPECT_EQ(report["frames"], 12);
    const nlohmann::json& skinned = report["files"][0];
    const nlohmann::json& sequence = report["files"][1];
    EXPECT_EQ(skinned["format"], "skinned-animation");
    EXPECT_EQ(skinned["frames"], 12);
    EXPECT_EQ(skinned["fps"], 25);
    EXPECT_EQ(skinned["joints"], kCanonicalJointCount + 2);
    EXPECT_EQ(skinned["vertices"], w.mesh.num_vertices());
    EXPECT_EQ(skinned["apparelVertices"], apparel);
    EXPECT_EQ(sequence["format"], "mesh-sequence");
    EXPECT_EQ(sequence["frames"], 12);
    // The readout is in cm: 1e-4 m is 0.01.
    ASSERT_TRUE(report["pmdA"].contains("skinned animation")) << report.dump();
    EXPECT_LT(report["pmdA"]["skinned animation"].get<double>(), 0.01);
    const nlohmann::json& per_frame = report["pmdAFrames"]["skinned animation"];
    ASSERT_EQ(per_frame.size(), 12u) << report.dump();
    for (size_t k = 0; k < per_frame.size(); ++k) EXPECT_LT(per_frame[k].get<double>(), 0.01) << "frame " << k;
    for (const char* side : {"min", "max"}) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(skinned["box"][side][c].get<double>(), sequence["box"][side][c].get<double>(), 1e-4)
            << "box " << side << " " << c;
      }
    }
  }
}

TEST(ViewerFolder, AFolderOfTheUsersIsRefusedBeforeAnyWork) {
  const fs::path dir = test::temp_dir("viewer_users_folder");
  std::ofstream(dir / "thesis.tex") << "keep me";
  const test::CommandResult r = test::run_command(
      amt_command({"animate", "--character", "generated:7:2000", "--motion",
                   std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_01.bvh", "--html", dir.string(), "--quiet"}));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(dir.string() + ": expected an empty folder or a viewer folder amt wrote"), std::string::npos)
      << r.err;
  EXPECT_EQ(test::read_file_bytes(dir / "thesis.tex"), "keep me");
  EXPECT_FALSE(fs::exists(dir / "viewer.json"));
}

// A viewer folder amt wrote, with a symbolic link put inside it (its three/ folder pointing at the user's own
// folder): rewriting it is refused before any work, naming the link, and the user's file is untouched.
TEST(ViewerFolder, ALinkInsideAViewerFolderIsRefusedAndNeverWrittenThrough) {
  const fs::path dir = write_animate_folder(test::temp_dir("viewer_link") / "viewer");
  const fs::path users = dir.parent_path() / "users";
  fs::create_directories(users / "build");
  std::ofstream(users / "build" / "three.module.js") << "keep me";
  fs::remove_all(dir / "three");
  fs::create_directory_symlink(users, dir / "three");
  const test::CommandResult r = test::run_command(amt_command(
      {"animate", "--character", "generated:7:2000", "--motion", std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_01.bvh",
       "--frames", "4", "--html", dir.string(), "--bind", "none", "--threads", "1", "--quiet"}));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find((dir / "three").string() + ": a symbolic link inside the viewer folder"), std::string::npos)
      << r.err;
  EXPECT_EQ(test::read_file_bytes(users / "build" / "three.module.js"), "keep me");
}

// `--html DIR` without `--out`: the bind cache lives in the folder (DIR/prediction.bind), and a second run
// replaces the folder and loads the cache instead of refusing a folder that holds it.
TEST(ViewerFolder, HtmlWithoutOutKeepsItsBindCacheInTheFolderAndRunsAgain) {
  const fs::path dir = test::temp_dir("viewer_html_only") / "viewer";
  const std::vector<std::string> args = {
      "animate",  "--character", "generated:7:2000", "--motion",   std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_01.bvh",
      "--frames", "4",           "--html",           dir.string(), "--threads",
      "1"};
  const test::CommandResult first = test::run_command(amt_command(args));
  ASSERT_EQ(first.status, 0) << first.err;
  EXPECT_NE(first.out.find("computed, cached in " + (dir / "prediction.bind").string()), std::string::npos)
      << first.out;
  for (const char* file : {"viewer.json", "index.html", "prediction.glb", "skinning.glb", "prediction.bind"})
    EXPECT_TRUE(fs::is_regular_file(dir / file)) << file;
  const test::CommandResult second = test::run_command(amt_command(args));
  ASSERT_EQ(second.status, 0) << second.err;
  EXPECT_NE(second.out.find("cache hit: " + (dir / "prediction.bind").string()), std::string::npos) << second.out;
}

TEST(ViewCli, AFileThatIsNotAGlbIsAOneLineError) {
  const fs::path dir = test::temp_dir("view_not_glb");
  std::ofstream(dir / "notes.glb") << "these are notes, not a binary glTF";
  const test::CommandResult r = test::run_command(amt_command({"view", (dir / "notes.glb").string()}) + "; " +
                                                  amt_command({"view", dir.string()}));
  EXPECT_NE(r.err.find("notes.glb: header: expected the GLB magic 'glTF'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(dir.string() + ": expected a viewer folder"), std::string::npos) << r.err;
  EXPECT_EQ(r.status, 1);
}

// One HTTP/1.1 request to 127.0.0.1:`port` over a plain socket (no client library in the tests): the status
// code and the body's length (-1: no answer).
struct HttpAnswer {
  int status = -1;
  long body = -1;
};
HttpAnswer http_get(int port, const std::string& path, const std::string& headers = "") {
  HttpAnswer answer;
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return answer;
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  timeval timeout{10, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0) {
    const std::string host =
        headers.find("Host:") == std::string::npos ? "Host: 127.0.0.1:" + std::to_string(port) + "\r\n" : "";
    const std::string request = "GET " + path + " HTTP/1.1\r\n" + host + headers + "Connection: close\r\n\r\n";
    if (send(fd, request.data(), request.size(), 0) == ssize_t(request.size())) {
      std::string reply;
      char buffer[65536];
      for (ssize_t n; (n = recv(fd, buffer, sizeof(buffer), 0)) > 0;) reply.append(buffer, size_t(n));
      const size_t space = reply.find(' '), end = reply.find("\r\n\r\n");
      if (space != std::string::npos && end != std::string::npos) {
        answer.status = std::atoi(reply.c_str() + space + 1);
        answer.body = long(reply.size() - end - 4);
      }
    }
  }
  close(fd);
  return answer;
}

// `amt view DIR` serves only the folder's own regular files (no link out of it, no dotfiles), only to requests
// that name 127.0.0.1 or localhost at its port, and one byte range per request.
TEST(ViewServer, AFolderServesItsOwnFilesOnlyToLocalPages) {
  const fs::path dir = write_animate_folder(test::temp_dir("view_server") / "viewer");
  const fs::path outside = dir.parent_path() / "outside.txt";
  std::ofstream(outside) << "a file of the user's\n";
  fs::create_symlink(outside, dir / "link");
  fs::create_symlink(dir / "index.html", dir / "inside_link.html");  // a link that stays inside: served
  std::ofstream(dir / ".hidden") << "dotfile\n";
  const ViewServer server({dir.string()});
  ASSERT_FALSE(server.url().empty()) << server.printed();
  const int port = std::atoi(server.url().c_str() + server.url().rfind(':') + 1);
  ASSERT_GT(port, 0) << server.url();
  const long page = long(fs::file_size(dir / "index.html"));
  EXPECT_EQ(http_get(port, "/").status, 200);
  EXPECT_EQ(http_get(port, "/index.html").body, page);
  EXPECT_EQ(http_get(port, "/inside_link.html").body, page);
  EXPECT_EQ(http_get(port, "/prediction.glb").body, long(fs::file_size(dir / "prediction.glb")));
  EXPECT_EQ(http_get(port, "/link").status, 404);            // a link out of the folder
  EXPECT_EQ(http_get(port, "/.hidden").status, 404);         // a dotfile
  EXPECT_EQ(http_get(port, "/../outside.txt").status, 404);  // climbing out
  EXPECT_EQ(http_get(port, "/three").status, 404);           // a folder
  EXPECT_EQ(http_get(port, "/index.html", "Host: localhost:" + std::to_string(port) + "\r\n").status, 200);
  EXPECT_EQ(http_get(port, "/index.html", "Host: attacker.example:" + std::to_string(port) + "\r\n").status, 403);
  const HttpAnswer one = http_get(port, "/prediction.glb", "Range: bytes=0-3\r\n");
  EXPECT_EQ(one.status, 206);
  EXPECT_EQ(one.body, 4);
  EXPECT_EQ(http_get(port, "/prediction.glb", "Range: bytes=0-3,0-3,0-3\r\n").status, 416);
}

}  // namespace
}  // namespace amt
