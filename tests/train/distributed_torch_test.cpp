// Data-parallel training (train/distributed.h, issue 15): the rendezvous URL and torchrun's environment
// variables, the ranks' shares of the samples, the gradient average and broadcast of a process group on
// two threads, and `amt train` started as two local processes on the loopback interface: the same loss
// curve and weights as one process with the whole batch, files written by rank 0 alone, an exact resume,
// a killed rank that stops the other with one clear line within the timeout, and a run killed whole that
// resumes at the same rendezvous (tests/train/rendezvous_store_torch_test.cpp: the rendezvous itself).
#include "train/distributed.h"

#include <ATen/ATen.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "micro_dataset.h"
#include "models/checkpoint.h"
#include "tests/test_support.h"
#include "train/samples.h"

extern char** environ;

namespace amt {
namespace {

namespace fs = std::filesystem;
using test::error_of;

fs::path test_dir() {
  static const fs::path dir = test::test_directory("amt_distributed_test");
  return dir;
}

// An environment for resolve_distributed_options.
std::function<const char*(const char*)> environment(std::map<std::string, std::string> variables) {
  auto held = std::make_shared<std::map<std::string, std::string>>(std::move(variables));
  return [held](const char* name) -> const char* {
    const auto it = held->find(name);
    return it == held->end() ? nullptr : it->second.c_str();
  };
}

// Command-line values: nothing given.
DistributedOptions not_given() {
  return DistributedOptions{0, -1, "", 300.0, ""};
}

// === The rendezvous URL and the environment

TEST(Rendezvous, ParsesTcpAndFileAndRejectsAnythingElse) {
  const Rendezvous tcp = parse_rendezvous("tcp://10.0.0.7:29500");
  EXPECT_EQ(tcp.scheme, "tcp");
  EXPECT_EQ(tcp.host, "10.0.0.7");
  EXPECT_EQ(tcp.port, 29500);
  const Rendezvous ipv6 = parse_rendezvous("tcp://[::1]:1234");
  EXPECT_EQ(ipv6.host, "::1");
  EXPECT_EQ(ipv6.port, 1234);
  const Rendezvous file = parse_rendezvous("file:///shared/run1/rendezvous");
  EXPECT_EQ(file.scheme, "file");
  EXPECT_EQ(file.path, "/shared/run1/rendezvous");
  for (const std::string bad : {"", "10.0.0.7:29500", "tcp://10.0.0.7", "tcp://:29500", "tcp://host:0",
                                "tcp://host:65536", "tcp://host:29x", "http://host:80", "file://"}) {
    const std::string message = error_of([&] { parse_rendezvous(bad); });
    EXPECT_EQ(message.rfind("--rendezvous: expected tcp://HOST:PORT", 0), 0u) << bad << ": " << message;
    EXPECT_NE(message.find("found '" + bad + "'"), std::string::npos) << message;
  }
}

TEST(DistributedOptions, TorchrunsEnvironmentGivesTheRunAndTheCommandLineWins) {
  const auto torchrun = environment({{"WORLD_SIZE", "4"},
                                     {"RANK", "3"},
                                     {"MASTER_ADDR", "node7"},
                                     {"MASTER_PORT", "29500"},
                                     {"AMT_DIST_TOKEN", "0123456789abcdef0123"}});
  const DistributedOptions from_env = resolve_distributed_options(not_given(), torchrun);
  EXPECT_EQ(from_env.world_size, 4);
  EXPECT_EQ(from_env.rank, 3);
  EXPECT_EQ(from_env.rendezvous, "tcp://node7:29500");
  EXPECT_EQ(from_env.token, "0123456789abcdef0123");
  DistributedOptions given = not_given();
  given.rank = 1;
  given.rendezvous = "file:///shared/r";
  const DistributedOptions mixed = resolve_distributed_options(given, torchrun);
  EXPECT_EQ(mixed.world_size, 4);
  EXPECT_EQ(mixed.rank, 1);
  EXPECT_EQ(mixed.rendezvous, "file:///shared/r");
  // Nothing anywhere: a process on its own.
  const DistributedOptions alone = resolve_distributed_options(not_given(), environment({}));
  EXPECT_EQ(alone.world_size, 1);
  EXPECT_EQ(alone.rank, 0);
}

TEST(DistributedOptions, BadValuesNameTheOptionOrVariable) {
  const auto options = [](int world, int rank, std::string rendezvous, double timeout = 300.0) {
    return DistributedOptions{world, rank, std::move(rendezvous), timeout, ""};
  };
  const std::vector<std::pair<std::string, std::string>> cases = {
      {error_of([&] { resolve_distributed_options(options(2, 2, "tcp://h:1"), environment({})); }),
       "--rank 2: expected a rank in [0, 2) (--world-size 2)"},
      {error_of([&] { resolve_distributed_options(options(2, -1, "tcp://h:1"), environment({})); }),
       "--rank: expected this process's rank in [0, 2)"},
      {error_of([&] { resolve_distributed_options(options(2, 0, ""), environment({})); }),
       "--rendezvous: expected tcp://HOST:PORT or file://PATH with --world-size 2, found none"},
      {error_of([&] { resolve_distributed_options(options(2, 0, "tcp//h:1"), environment({})); }),
       "--rendezvous: expected tcp://HOST:PORT"},
      {error_of([&] { resolve_distributed_options(options(2, 0, "tcp://h:1", 0.0), environment({})); }),
       "--dist-timeout: expected seconds > 0, found 0"},
      {error_of([&] {
         resolve_distributed_options(not_given(), environment({{"WORLD_SIZE", "two"}}));
       }),
       "WORLD_SIZE: expected the number of ranks, an integer >= 1, found 'two'"},
      {error_of([&] {
         resolve_distributed_options(not_given(), environment({{"WORLD_SIZE", "2"}, {"RANK", "5"}}));
       }),
       "RANK 5: expected a rank in [0, 2) (WORLD_SIZE 2)"},
      {error_of([&] {
         resolve_distributed_options(not_given(),
                                     environment({{"WORLD_SIZE", "2"}, {"RANK", "0"}, {"MASTER_PORT", "29500"}}));
       }),
       "MASTER_ADDR: expected rank 0's address along with MASTER_PORT 29500, found none"},
      {error_of([&] {
         resolve_distributed_options(
             not_given(),
             environment({{"WORLD_SIZE", "2"}, {"RANK", "0"}, {"MASTER_ADDR", "h"}, {"MASTER_PORT", "99999"}}));
       }),
       "MASTER_PORT: expected a port in [1, 65535] along with MASTER_ADDR h, found '99999'"},
  };
  for (const auto& [message, expected] : cases) EXPECT_EQ(message.rfind(expected, 0), 0u) << message;
}

// === Shares of the samples

TEST(SampleShare, RanksTakeDisjointSharesWhoseUnionIsTheWholeBatch) {
  // Rank 1 of 2 with 2 samples per step: samples 2, 3 at step 0, 6, 7 at step 1 (hand-computed).
  const SampleShare rank1{2, 2, 1};
  EXPECT_EQ((std::vector<int64_t>{rank1.sample(0), rank1.sample(1), rank1.sample(2), rank1.sample(3)}),
            (std::vector<int64_t>{2, 3, 6, 7}));
  // 3 ranks x 2 samples over 4 steps: every sample 0 .. 23 once, each step's in that step's block of 6.
  std::multiset<int64_t> taken;
  for (int rank = 0; rank < 3; ++rank) {
    const SampleShare share{2, 3, rank};
    for (int64_t j = 0; j < 8; ++j) {
      taken.insert(share.sample(j));
      EXPECT_EQ(share.sample(j) / 6, j / 2) << "rank " << rank << " sample " << j;
    }
  }
  std::multiset<int64_t> whole;
  for (int64_t k = 0; k < 24; ++k) whole.insert(k);
  EXPECT_EQ(taken, whole);
}

// === A process group of two threads

// Runs f(rank, group) on two threads joined at a fresh file:// rendezvous; rethrows a thread's failure.
void with_two_ranks(const std::string& name, const std::function<void(int, DataParallelGroup&)>& f) {
  const std::string rendezvous = "file://" + (test_dir() / (name + ".rendezvous")).string();
  std::vector<std::string> errors(2);
  std::vector<std::thread> threads;
  for (int rank = 0; rank < 2; ++rank) {
    threads.emplace_back([&, rank] {
      try {
        DataParallelGroup group(DistributedOptions{2, rank, rendezvous, 20.0, ""});
        f(rank, group);
      } catch (const std::exception& e) {
        errors[rank] = e.what();
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(errors[0], "");
  EXPECT_EQ(errors[1], "");
}

TEST(DataParallelGroup, AveragesGradientsAndLossesAndBroadcastsRankZerosValues) {
  std::vector<std::vector<float>> averaged(2), broadcast(2);
  std::vector<std::vector<double>> values(2);
  std::vector<std::vector<bool>> defined(2);
  with_two_ranks("average", [&](int rank, DataParallelGroup& group) {
    EXPECT_EQ(group.rank(), rank);
    EXPECT_EQ(group.world_size(), 2);
    // a: both ranks have a gradient; b: rank 0 alone; c: neither.
    at::Tensor a = at::zeros({2}, at::kFloat).requires_grad_(), b = at::zeros({1, 2}, at::kFloat).requires_grad_(),
               c = at::zeros({3}, at::kFloat).requires_grad_();
    a.mutable_grad() = rank == 0 ? at::tensor({1.0f, 2.0f}) : at::tensor({3.0f, 5.0f});
    if (rank == 0) b.mutable_grad() = at::tensor({4.0f, -6.0f}).view({1, 2});
    std::vector<double> v = rank == 0 ? std::vector<double>{1.0, 10.0} : std::vector<double>{2.0, 30.0};
    group.average_gradients({a, b, c}, v, 0);
    values[rank] = v;
    for (const at::Tensor& g : {a.grad(), b.grad().flatten()})
      for (int64_t i = 0; i < g.numel(); ++i) averaged[rank].push_back(g[i].item<float>());
    defined[rank] = {a.grad().defined(), b.grad().defined(), c.grad().defined()};
    EXPECT_EQ(group.communication_count(), 1);
    // Rank 0's parameters and an integer buffer reach rank 1.
    at::Tensor p = at::full({3}, rank == 0 ? 0.25f : -1.0f), counts = at::full({2}, rank == 0 ? 7 : 0, at::kLong);
    group.broadcast_from_rank0({p, counts});
    broadcast[rank] = {p[0].item<float>(), p[2].item<float>(), static_cast<float>(counts[1].item<int64_t>())};
    group.barrier("the test");
  });
  for (int rank = 0; rank < 2; ++rank) {
    EXPECT_EQ(averaged[rank], (std::vector<float>{2.0f, 3.5f, 2.0f, -3.0f})) << "rank " << rank;
    EXPECT_EQ(values[rank], (std::vector<double>{1.5, 20.0})) << "rank " << rank;
    EXPECT_EQ(defined[rank], (std::vector<bool>{true, true, false})) << "rank " << rank;
    EXPECT_EQ(broadcast[rank], (std::vector<float>{0.25f, 0.25f, 7.0f})) << "rank " << rank;
  }
}

TEST(DataParallelGroup, RanksWithDifferentSettingsStopWithBothTexts) {
  std::vector<std::string> errors(2);
  with_two_ranks("same", [&](int rank, DataParallelGroup& group) {
    errors[rank] = error_of([&] { group.expect_same("the run", rank == 0 ? "seed 1" : "seed 2"); });
    group.barrier("the test");
  });
  EXPECT_EQ(errors[0], "");
  EXPECT_NE(errors[1].find("rank 1 of 2: the run: expected rank 0's seed 1, found seed 2"), std::string::npos)
      << errors[1];
}

// === `amt train` as local processes

// A child process running `amt args...` in `dir`, its stdout and stderr in files.
struct Child {
  pid_t pid = -1;
  fs::path out, err;
};

Child start_amt(const fs::path& dir, const std::string& name, const std::vector<std::string>& args) {
  Child child;
  child.out = dir / (name + ".out");
  child.err = dir / (name + ".err");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, child.out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, child.err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<std::string> words = {AMT_BINARY};
  words.insert(words.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& w : words) argv.push_back(w.data());
  argv.push_back(nullptr);
  const fs::path cwd = fs::current_path();
  fs::current_path(dir);
  const int status = posix_spawn(&child.pid, AMT_BINARY, &actions, nullptr, argv.data(), environ);
  fs::current_path(cwd);
  posix_spawn_file_actions_destroy(&actions);
  EXPECT_EQ(status, 0) << "cannot start " << AMT_BINARY;
  return child;
}

// Waits for the child; its exit status (-1: ended by a signal).
int finish(const Child& child) {
  int status = 0;
  waitpid(child.pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string text_of(const fs::path& path) {
  return test::read_file_bytes(path);
}

// A free TCP port on the loopback interface (bound, read and released).
int free_port() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = 0;
  bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address));
  socklen_t size = sizeof(address);
  getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size);
  close(fd);
  return ntohs(address.sin_port);
}

const std::string& micro_dataset() {
  static const std::string path = [] {
    const std::string p = (test_dir() / "micro.h5").string();
    test::write_micro_dataset(p);
    return p;
  }();
  return path;
}

// `amt train apparel` on the micro dataset with a small local apparel network, one thread, no validation.
std::vector<std::string> train_args(const std::string& out, int steps, int batch) {
  return {"train",
          "apparel",
          "--data",
          micro_dataset(),
          "--out",
          out,
          "--steps",
          std::to_string(steps),
          "--batch",
          std::to_string(batch),
          "--seed",
          "5",
          "--lr",
          "1e-3",
          "--apparel-options",
          R"({"edge_widths":[16,16],"decoder_widths":[16]})",
          "--unroll",
          "1:0.4,2:0.7,7:1",
          "--lr-decay-steps",
          "6",
          "--normalizer-samples",
          "4",
          "--validate-every",
          "0",
          "--checkpoint-every",
          "3",
          "--threads",
          "1",
          "--loader-threads",
          "0",
          "--quiet"};
}

std::vector<std::string> with(std::vector<std::string> args, const std::vector<std::string>& more) {
  args.insert(args.end(), more.begin(), more.end());
  return args;
}

// The loss column of a training log.
std::vector<double> losses(const fs::path& csv) {
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  std::vector<double> values;
  while (std::getline(in, line)) values.push_back(std::stod(line.substr(line.find(',') + 1)));
  return values;
}

// The parameters of a local apparel checkpoint, flattened.
at::Tensor weights(const fs::path& checkpoint) {
  CheckpointInfo info;
  ApparelDynamicsNet net =
      load_frozen_network<ApparelDynamicsNet, ApparelDynamicsOptions>(checkpoint.string(), ModuleKind::kApparel, info);
  std::vector<at::Tensor> flat;
  for (const at::Tensor& p : net->parameters()) flat.push_back(p.detach().flatten());
  return at::cat(flat);
}

// Runs the two ranks of a run to the end; both must succeed.
void run_two_ranks(const fs::path& dir, const std::string& name, const std::vector<std::string>& rank0,
                   const std::vector<std::string>& rank1) {
  const Child a = start_amt(dir, name + "_rank0", rank0), b = start_amt(dir, name + "_rank1", rank1);
  EXPECT_EQ(finish(a), 0) << text_of(a.err);
  EXPECT_EQ(finish(b), 0) << text_of(b.err);
}

// Two ranks with batch 2 follow one process with batch 4 over the same samples: every logged loss within
// 1e-6 relative (measured: equal in all 9 logged digits) and every weight after 6 steps within 1e-4, a
// tenth of one AdamW step at --lr 1e-3 (measured: 1e-5; the gradients are summed in another order, and
// AdamW's division by sqrt(v) turns rounding noise in a near-zero gradient into up to a step either way);
// only rank 0 writes; the run resumes exactly (also on one process taking the whole batch).
// A home folder of the test's own for the children: rank 0 of a loopback tcp:// run keeps its generated
// token in ~/.cache/amt.
void use_test_home() {
  const fs::path home = test_dir() / "home";
  fs::create_directories(home);
  setenv("HOME", home.c_str(), 1);
}

TEST(DataParallelTraining, TwoRanksFollowOneProcessWithTheWholeBatchAndOnlyRankZeroWrites) {
  use_test_home();
  const fs::path dir = test_dir() / "equivalence";
  fs::create_directories(dir);
  const Child one = start_amt(dir, "one", train_args("one", 6, 4));
  ASSERT_EQ(finish(one), 0) << text_of(one.err);

  const std::string rendezvous = "tcp://127.0.0.1:" + std::to_string(free_port());
  const auto rank = [&](int r, const std::string& out, int steps) {
    return with(train_args(out, steps, 2),
                {"--world-size", "2", "--rank", std::to_string(r), "--rendezvous", rendezvous, "--dist-timeout", "60"});
  };
  run_two_ranks(dir, "two", rank(0, "two", 6), rank(1, "two_rank1", 6));
  // Rank 0 wrote the checkpoint and the log, and said so; rank 1 wrote nothing.
  EXPECT_FALSE(fs::exists(dir / "two_rank1"));
  std::set<std::string> written;
  for (const auto& e : fs::directory_iterator(dir / "two")) written.insert(e.path().filename().string());
  EXPECT_EQ(written, (std::set<std::string>{"apparel.ckpt", "apparel.csv"}));
  EXPECT_NE(text_of(dir / "two_rank0.out").find("2 ranks, gradient exchange"), std::string::npos);
  EXPECT_NE(text_of(dir / "two_rank1.out").find("rank 1 of 2: steps 0 -> 6"), std::string::npos);

  const std::vector<double> single = losses(dir / "one" / "apparel.csv"),
                            parallel = losses(dir / "two" / "apparel.csv");
  ASSERT_EQ(single.size(), 6u);
  ASSERT_EQ(parallel.size(), 6u);
  double largest = 0.0;
  for (size_t i = 0; i < single.size(); ++i) {
    EXPECT_NEAR(parallel[i], single[i], 1e-6 * single[i]) << "step " << i + 1;
    largest = std::max(largest, std::abs(parallel[i] - single[i]) / single[i]);
  }
  EXPECT_NE(single[0], single[5]);  // the curve moves: the test compares a training run, not a constant
  const at::Tensor w1 = weights(dir / "one" / "apparel.ckpt"), w2 = weights(dir / "two" / "apparel.ckpt");
  const float weight_difference = (w1 - w2).abs().max().item<float>();
  EXPECT_LT(weight_difference, 1e-4f);
  std::cout << "two ranks vs one process: largest relative loss difference " << largest
            << ", largest weight difference " << weight_difference << " (of " << w1.numel() << " weights)\n";

  // Resume: 3 steps on two ranks, then 3 more from the checkpoint, equal the 6 straight steps bit for bit;
  // one process resuming the two ranks' checkpoint takes both shares (batch 4) and follows them.
  run_two_ranks(dir, "first", rank(0, "split", 3), rank(1, "split_rank1", 3));
  fs::copy_file(dir / "split" / "apparel.ckpt", dir / "step3.ckpt");
  run_two_ranks(dir, "second", with(rank(0, "split", 6), {"--resume", "split/apparel.ckpt"}),
                with(rank(1, "split_rank1", 6), {"--resume", "split/apparel.ckpt"}));
  EXPECT_EQ(losses(dir / "split" / "apparel.csv"), parallel);
  const Child alone = start_amt(dir, "alone", with(train_args("alone", 6, 1), {"--resume", "step3.ckpt"}));
  ASSERT_EQ(finish(alone), 0) << text_of(alone.err);
  EXPECT_NE(text_of(alone.out).find("steps 3 -> 6"), std::string::npos) << text_of(alone.out);
  const std::vector<double> resumed_alone = losses(dir / "alone" / "apparel.csv");
  ASSERT_EQ(resumed_alone.size(), 3u);
  for (size_t i = 0; i < 3; ++i) EXPECT_NEAR(resumed_alone[i], parallel[3 + i], 1e-6 * parallel[3 + i]);
}

// Rank 1 is killed mid-run: rank 0 stops within the timeout with one line naming the run, its rank, the
// lost exchange and --dist-timeout, and its last checkpoint resumes.
TEST(DataParallelTraining, AKilledRankStopsTheOtherWithinTheTimeout) {
  const fs::path dir = test_dir() / "fault";
  fs::create_directories(dir);
  const std::string rendezvous = "file://" + (dir / "rendezvous").string();
  const auto rank = [&](int r) {
    return with(train_args("out", 100000, 1),
                {"--world-size", "2", "--rank", std::to_string(r), "--rendezvous", rendezvous, "--dist-timeout", "5"});
  };
  const Child rank0 = start_amt(dir, "rank0", rank(0)), rank1 = start_amt(dir, "rank1", rank(1));
  // Both ranks are past step 4 (rank 0 logs a step once the gradients of both are in) ...
  const auto logged = [&] {
    std::ifstream in(dir / "out" / "apparel.csv");
    std::string line;
    int n = 0;
    while (std::getline(in, line)) ++n;
    return n - 1;
  };
  for (int i = 0; i < 1200 && logged() < 4; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_GE(logged(), 4) << text_of(dir / "rank0.err") << text_of(dir / "rank1.err");
  // ... when rank 1 dies.
  kill(rank1.pid, SIGKILL);
  const auto killed = std::chrono::steady_clock::now();
  EXPECT_EQ(finish(rank1), -1);
  EXPECT_EQ(finish(rank0), 1);
  // No bound on the wall time here (ctest runs this beside other tests on a shared machine; a hang ends at the
  // ctest's timeout): the message below says that rank 0 stopped on --dist-timeout, not on something else.
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  std::cout << "rank 0 stopped " << seconds << " s after rank 1 was killed\n";
  const std::string err = text_of(rank0.err);
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_EQ(
      err.rfind("amt: error: data-parallel run " + rendezvous + ", rank 0 of 2: the gradient all-reduce of step ", 0),
      0u)
      << err;
  EXPECT_NE(err.find("failed: another rank stopped or did not answer within 5 s (--dist-timeout)"), std::string::npos)
      << err;
  EXPECT_NE(err.find("restart every rank with --resume from the last checkpoint"), std::string::npos) << err;
  EXPECT_EQ(text_of(rank0.out), "");
  // The last checkpoint (every 3 steps) is whole and resumes.
  const CheckpointInfo info = read_checkpoint_info((dir / "out" / "apparel.ckpt").string(), ModuleKind::kApparel);
  EXPECT_GE(info.step, 3);
  EXPECT_EQ(info.step % 3, 0);
}

// A rank that never comes: the other stops after the timeout, naming the missing rank; the file rendezvous
// is removed so that a restart starts afresh.
TEST(DataParallelTraining, ARankThatNeverJoinsIsNamedAfterTheTimeout) {
  const fs::path dir = test_dir() / "absent";
  fs::create_directories(dir);
  const std::string rendezvous = "file://" + (dir / "rendezvous").string();
  const Child rank0 = start_amt(dir, "rank0",
                                with(train_args("out", 3, 1), {"--world-size", "3", "--rank", "0", "--rendezvous",
                                                               rendezvous, "--dist-timeout", "2"}));
  const Child rank2 = start_amt(dir, "rank2",
                                with(train_args("out", 3, 1), {"--world-size", "3", "--rank", "2", "--rendezvous",
                                                               rendezvous, "--dist-timeout", "2"}));
  EXPECT_EQ(finish(rank0), 1);
  EXPECT_EQ(finish(rank2), 1);
  const std::string err = text_of(rank0.err);
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_NE(err.find("rank 0 of 3: rank(s) 1 did not join within 2 s (--dist-timeout; start every rank with the same "
                     "--world-size 3 and --rendezvous)"),
            std::string::npos)
      << err;
  EXPECT_FALSE(fs::exists(dir / "rendezvous"));
  EXPECT_FALSE(fs::exists(dir / "out"));
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().rfind("rendezvous", 0), std::string::npos) << e.path() << " left";
}

// Every rank killed with kill -9, then the same commands with --resume, rank 1 first: rank 1 waits past the
// stale marker the killed run left (it used to join the stale store and hang past --dist-timeout), rank 0
// replaces it with a new run, and the run ends normally.
TEST(DataParallelTraining, AfterEveryRankIsKilledTheResumedRunReplacesTheStaleStore) {
  const fs::path dir = test_dir() / "killed";
  fs::create_directories(dir);
  const std::string rendezvous = "file://" + (dir / "rendezvous").string();
  const auto rank = [&](int r, int steps) {
    return with(train_args("out", steps, 1),
                {"--world-size", "2", "--rank", std::to_string(r), "--rendezvous", rendezvous, "--dist-timeout", "60"});
  };
  const Child rank0 = start_amt(dir, "rank0", rank(0, 100000)), rank1 = start_amt(dir, "rank1", rank(1, 100000));
  const fs::path checkpoint = dir / "out" / "apparel.ckpt";
  for (int i = 0; i < 2400 && !fs::exists(checkpoint); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_TRUE(fs::exists(checkpoint)) << text_of(dir / "rank0.err") << text_of(dir / "rank1.err");
  kill(rank0.pid, SIGKILL);
  kill(rank1.pid, SIGKILL);
  EXPECT_EQ(finish(rank0), -1);
  EXPECT_EQ(finish(rank1), -1);
  // The killed run's marker and store are still there.
  ASSERT_TRUE(fs::exists(dir / "rendezvous"));
  const int step = static_cast<int>(read_checkpoint_info(checkpoint.string(), ModuleKind::kApparel).step);
  const auto resumed = [&](int r) { return with(rank(r, step + 2), {"--resume", "out/apparel.ckpt"}); };
  const Child again1 = start_amt(dir, "again1", resumed(1));
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  const Child again0 = start_amt(dir, "again0", resumed(0));
  EXPECT_EQ(finish(again1), 0) << text_of(dir / "again1.err");
  EXPECT_EQ(finish(again0), 0) << text_of(dir / "again0.err");
  EXPECT_NE(text_of(dir / "again0.out").find("steps " + std::to_string(step) + " -> " + std::to_string(step + 2)),
            std::string::npos)
      << text_of(dir / "again0.out");
  // Neither the stale files nor the new run's are left.
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().rfind("rendezvous", 0), std::string::npos) << e.path() << " left";
}

// Bad options fail before anything is written, with one line naming the option, and status 1 or 2.
TEST(DataParallelTraining, BadOptionsGiveOneLineAndWriteNothing) {
  use_test_home();
  const fs::path dir = test_dir() / "bad";
  fs::create_directories(dir);
  const std::string port = std::to_string(free_port());
  const std::string notes = "my notes\n";
  { std::ofstream(dir / "notes.txt") << notes; }
  struct Case {
    std::vector<std::string> args;
    std::string expected;
    int status;
  };
  const std::vector<Case> cases = {
      {{"--world-size", "2", "--rank", "2", "--rendezvous", "tcp://127.0.0.1:" + port},
       "amt: error: --rank 2: expected a rank in [0, 2) (--world-size 2)",
       1},
      {{"--world-size", "2", "--rank", "0", "--rendezvous", "127.0.0.1:" + port},
       "amt: error: --rendezvous: expected tcp://HOST:PORT (rank 0's address and a free port) or file://PATH (a file "
       "every rank sees), found '127.0.0.1:" +
           port + "'",
       1},
      {{"--world-size", "2", "--rank", "1"}, "amt: error: --rendezvous: expected tcp://HOST:PORT or file://PATH", 1},
      {{"--world-size", "2", "--rank", "1", "--rendezvous", "file://no-such-folder/rendezvous"},
       "amt: error: --rendezvous file://no-such-folder/rendezvous: no folder " + (dir / "no-such-folder").string() +
           " (expected file://PATH in a folder every rank sees)",
       1},
      // Rank 1 finds no rank 0 listening: the store is unreachable.
      {{"--world-size", "2", "--rank", "1", "--rendezvous", "tcp://127.0.0.1:" + port, "--dist-timeout", "1"},
       "amt: error: data-parallel run tcp://127.0.0.1:" + port +
           ", rank 1 of 2: cannot reach the rendezvous within 1 s (--rendezvous, --dist-timeout)",
       1},
      {{"--world-size", "0"}, "--world-size", 2},
      // A user's file is no rendezvous: refused at once, and left as it was.
      {{"--world-size", "2", "--rank", "1", "--rendezvous", "file://notes.txt"},
       "amt: error: data-parallel run file://notes.txt, rank 1 of 2: --rendezvous: notes.txt is a file amt did not "
       "write, not a rendezvous amt made",
       1},
      {{"--world-size", "2", "--rank", "0", "--rendezvous", "file://notes.txt"},
       "amt: error: data-parallel run file://notes.txt, rank 0 of 2: --rendezvous: notes.txt is a file amt did not "
       "write, not a rendezvous amt made",
       1},
      // Any address but loopback wants the shared token.
      {{"--world-size", "2", "--rank", "0", "--rendezvous", "tcp://192.0.2.7:" + port},
       "amt: error: --dist-token: the rendezvous tcp://192.0.2.7:" + port +
           " is not on a loopback address, so every rank must present a shared token",
       1},
      {{"--world-size", "2", "--rank", "0", "--rendezvous", "tcp://127.0.0.1:" + port, "--dist-token", "secret"},
       "amt: error: --dist-token: expected a shared token of 16 to 256 printable characters without spaces",
       1},
  };
  for (const Case& c : cases) {
    const test::CommandResult r = test::run_command(
        "cd '" + dir.string() + "' && " + test::shell_command(AMT_BINARY, with(train_args("out", 3, 1), c.args)));
    EXPECT_EQ(r.status, c.status) << r.err;
    EXPECT_EQ(r.out, "");
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.err.rfind(c.expected, 0) == 0 || (c.status == 2 && r.err.find(c.expected) != std::string::npos), true)
        << r.err;
  }
  EXPECT_FALSE(fs::exists(dir / "out"));
  EXPECT_EQ(text_of(dir / "notes.txt"), notes);
}

}  // namespace
}  // namespace amt
