// `amt animate` as a user runs it, in a child process: exit codes, messages and what is left on disk
// when a run is stopped by a signal (issue 19: no temporary left, a good output untouched) and when
// the disk is full (one line naming the file, no abort, no crash at exit, no temporary left).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "data_tools/formats/gltf_import.h"
#include "tests/infer/runtime_fixture.h"
#include "tests/test_support.h"

extern char** environ;

namespace amt {
namespace {

namespace fs = std::filesystem;

// `amt animate` of the fixture's capsules with `motion` into `out`, plus `extra` arguments.
std::vector<std::string> animate_args(const test::RuntimeFixture& f, const std::string& motion, const std::string& out,
                                      const std::vector<std::string>& extra = {}) {
  std::vector<std::string> args = {"animate",
                                   "--character",
                                   f.data + ":capsules",
                                   "--motion",
                                   motion,
                                   "--model",
                                   f.model,
                                   "--apparel-mask",
                                   f.mask,
                                   "--out",
                                   out,
                                   "--threads",
                                   "1",
                                   "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  return args;
}

std::string shell_command(const std::vector<std::string>& args) {
  return test::shell_command(AMT_BINARY, args);
}

// Starts the amt program with `args`, its stdout and stderr going to `log`.
pid_t spawn_amt(const std::vector<std::string>& args, const std::string& log) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  std::vector<std::string> all = {AMT_BINARY};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  const int error = posix_spawn(&pid, AMT_BINARY, &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  return error == 0 ? pid : -1;
}

// Waits until `ready()` or the child's exit (polling; no time limit is asserted, 5 minutes at most).
// Returns false when the child exited first (its status in `status`).
template <typename Ready>
bool wait_for(pid_t pid, Ready ready, int& status) {
  for (int i = 0; i < 30000; ++i) {
    if (ready()) return true;
    if (waitpid(pid, &status, WNOHANG) == pid) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

// Stops the run of `args` with `signal` once `started()` and returns its exit code (-1: no exit).
template <typename Started>
int stop_mid_run(const std::vector<std::string>& args, const std::string& log, int signal, Started started) {
  const pid_t pid = spawn_amt(args, log);
  EXPECT_GT(pid, 0);
  if (pid <= 0) return -1;
  int status = 0;
  const bool running = wait_for(pid, started, status);
  EXPECT_TRUE(running) << "the run ended before it wrote a frame: " << test::read_file_bytes(log);
  if (running) {
    kill(pid, signal);
    waitpid(pid, &status, 0);
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A long motion: the longest CMU clip of data/ resampled to 1000 fps (about 15000 frames).
const std::string kLongMotion = std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_05.bvh";

// The streaming vertex cache (--vertex-cache) writes its frames to a temporary as they come: a signal mid-run
// removes it. (A skinned GLB keeps its joints' transforms in memory and writes nothing before the end.)
TEST(AnimateCli, SigtermMidRunRemovesTheTemporariesAndKeepsTheGoodOutput) {
  const test::RuntimeFixture f = test::make_runtime_fixture("cli_sigterm");
  const std::string out = (f.dir / "walk.glb").string();
  const test::CommandResult first =
      test::run_command(shell_command(animate_args(f, f.data + ":walk0", out, {"--vertex-cache"})));
  ASSERT_EQ(first.status, 0) << first.err;
  const std::string good = test::read_file_bytes(out);
  ASSERT_GT(good.size(), 100u);
  const std::string log = (f.dir / "log.txt").string();
  const int code =
      stop_mid_run(animate_args(f, kLongMotion, out, {"--fps", "1000", "--vertex-cache"}), log, SIGTERM, [&] {
        std::error_code e;
        return fs::file_size(out + ".frames.amt-tmp", e) > 0 && !e;
      });
  EXPECT_EQ(code, 128 + SIGTERM) << test::read_file_bytes(log);
  EXPECT_NE(test::read_file_bytes(log).find("amt: stopped by SIGTERM; removed 1 temporary file"), std::string::npos)
      << test::read_file_bytes(log);
  EXPECT_FALSE(fs::exists(out + ".frames.amt-tmp"));
  EXPECT_FALSE(fs::exists(out + ".amt-tmp"));
  EXPECT_EQ(test::read_file_bytes(out), good);
}

// A closed terminal (SIGHUP) and SIGQUIT stop a run as SIGTERM does: temporaries removed, the earlier output kept.
TEST(AnimateCli, SighupAndSigquitMidRunRemoveTheTemporaries) {
  const test::RuntimeFixture f = test::make_runtime_fixture("cli_sighup");
  const std::string out = (f.dir / "walk.glb").string();
  for (const int signal : {SIGHUP, SIGQUIT}) {
    const std::string name = signal == SIGHUP ? "SIGHUP" : "SIGQUIT";
    const std::string log = (f.dir / (name + ".txt")).string();
    const int code =
        stop_mid_run(animate_args(f, kLongMotion, out, {"--fps", "1000", "--vertex-cache"}), log, signal, [&] {
          std::error_code e;
          return fs::file_size(out + ".frames.amt-tmp", e) > 0 && !e;
        });
    EXPECT_EQ(code, 128 + signal) << test::read_file_bytes(log);
    EXPECT_NE(test::read_file_bytes(log).find("amt: stopped by " + name + "; removed 1 temporary file"),
              std::string::npos)
        << test::read_file_bytes(log);
    EXPECT_FALSE(fs::exists(out + ".frames.amt-tmp")) << name;
    EXPECT_FALSE(fs::exists(out + ".amt-tmp")) << name;
    EXPECT_FALSE(fs::exists(out)) << name;  // nothing was there before: nothing half-written is left
  }
}

TEST(AnimateCli, SigintMidRunRemovesTheTemporaryObjFolder) {
  const test::RuntimeFixture f = test::make_runtime_fixture("cli_sigint");
  const std::string out = (f.dir / "frames").string();
  const std::string log = (f.dir / "log.txt").string();
  const int code = stop_mid_run(animate_args(f, kLongMotion, out, {"--fps", "1000"}), log, SIGINT, [&] {
    std::error_code e;
    auto it = fs::directory_iterator(out + ".amt-tmp", e);
    return !e && std::distance(it, fs::directory_iterator()) >= 3;  // the marker and two frames
  });
  EXPECT_EQ(code, 128 + SIGINT) << test::read_file_bytes(log);
  EXPECT_FALSE(fs::exists(out + ".amt-tmp"));
  EXPECT_FALSE(fs::exists(out));
  EXPECT_TRUE(fs::exists(f.dir / "frames.bind"));  // the finished bind cache stays
}

// The shell commands that give the amt program a file size limit of `blocks` 512-byte blocks, with
// SIGXFSZ ignored so that writes past it fail with EFBIG: a full disk, without root or a mount. ""
// when the shell cannot set the limit.
std::string full_disk_prefix(int blocks) {
  const std::string prefix = "ulimit -f " + std::to_string(blocks) + " && trap '' XFSZ && ";
  return test::run_command(prefix + "true").status == 0 ? prefix : "";
}

size_t count_lines(const std::string& text) {
  return size_t(std::count(text.begin(), text.end(), '\n'));
}

TEST(AnimateCli, AFullDiskGivesOneLineErrorsAndLeavesNoTemporary) {
  const std::string full_disk = full_disk_prefix(8);  // 4 KiB
  if (full_disk.empty()) GTEST_SKIP() << "the shell cannot set a file size limit (ulimit -f): no full disk to simulate";
  const test::RuntimeFixture f = test::make_runtime_fixture("cli_full_disk");
  const fs::path d = f.dir;
  struct Case {
    std::string out, bind, expected;
  };
  const std::vector<Case> cases = {
      {"walk.glb", "none", (d / "walk.glb.frames.amt-tmp").string() + ": write: expected to write "},
      {"walk.h5", "none", (d / "walk.h5").string() + ": "},
      {"frames", "none", (d / "frames.amt-tmp").string() + "/frame_0000.obj.amt-tmp: write: expected "},
      {"bound.glb", (d / "walk.bind").string(),
       (d / "walk.bind.amt-tmp").string() + ": write: expected the whole bind cache written, found an error"}};
  for (const Case& c : cases) {
    const test::CommandResult r =
        test::run_command(full_disk + shell_command(animate_args(f, f.data + ":walk0", (d / c.out).string(),
                                                                 {"--bind", c.bind, "--vertex-cache"})));
    EXPECT_EQ(r.status, 1) << c.out << ": " << r.err;
    EXPECT_EQ(r.err.rfind("amt: error: " + c.expected, 0), 0u) << c.out << ": " << r.err;
    EXPECT_NE(r.err.find("File too large"), std::string::npos) << c.out << ": " << r.err;
    EXPECT_EQ(count_lines(r.err), 1u) << c.out << ": " << r.err;
  }
  // Nothing but the inputs is left: no output, no temporary, no bind cache.
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(d)) left.push_back(e.path().filename().string());
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"mask.txt", "micro.h5", "model"}));
}

// The shipped checkpoints (written before checkpoints carried payload_crc32) load and run.
TEST(AnimateCli, TheShippedModelAnimatesAGeneratedCharacter) {
  const fs::path dir = test::temp_dir("cli_shipped_model");
  const std::string out = (dir / "walk.glb").string();
  const std::string model = fs::path(AMT_ASSET_DIR).parent_path().string() + "/models/pretrained";
  const test::CommandResult r = test::run_command(shell_command(
      {"animate", "--character", "generated:7", "--motion", std::string(AMT_ASSET_DIR) + "/mocap/cmu/02_01.bvh",
       "--model", model, "--frames", "4", "--out", out, "--threads", "1", "--quiet"}));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out.rfind("wrote " + out + ", ", 0), 0u) << r.out;
  const GltfVertexAnimation frames = gltf_vertex_animation(read_gltf(out), "", 30.0f);
  ASSERT_EQ(frames.frames.size(), 4u);
  for (const MatrixX3f& V : frames.frames) {
    EXPECT_TRUE(V.allFinite());
    EXPECT_LT(V.cwiseAbs().maxCoeff(), 3.0f);  // a character of about 1-2 m near the origin
    EXPECT_GT(V.col(1).maxCoeff() - V.col(1).minCoeff(), 0.5f);
  }
}

}  // namespace
}  // namespace amt
