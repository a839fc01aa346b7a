// The web viewer (issue 16) end to end: `amt animate --html` writes a viewer folder, `amt view` serves
// it (or GLB files) on 127.0.0.1, and headless Chromium, driven by viewer/check_page.mjs through
// playwright-core, must load the animation, report its frames and meshes with no error and draw a
// screenshot that is not blank; a broken GLB must be reported by the page as a failure. When Chromium
// cannot start, the browser tests skip and say why (check_page.mjs exits 77).
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "data_tools/formats/gltf_export.h"
#include "data_tools/geometry/shapes.h"
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
