// The rendezvous of a data-parallel run (train/rendezvous_store.h, issue 34): amt's tcp:// store listens on
// the named address only (read from the kernel's socket table) and serves a client only after the run's
// token; every wait ends at its timeout; a file:// rendezvous refuses a user's file and leaves it as it
// was, and a stale marker left by a killed run is replaced, not joined.
#include "train/rendezvous_store.h"

#include <ATen/ATen.h>
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "tests/test_support.h"
#include "train/distributed.h"

namespace amt {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using test::error_of;
using Clock = std::chrono::steady_clock;

const std::string kToken = "0123456789abcdef0123456789abcdef";

RendezvousStore::Options store_options(int port, bool serve, const std::string& token, milliseconds timeout) {
  RendezvousStore::Options o;
  o.host = "127.0.0.1";
  o.port = port;
  o.serve = serve;
  o.token = token;
  o.timeout = timeout;
  return o;
}

// The listening TCP sockets on `port` from /proc/net/tcp: their local IPv4 addresses as the kernel
// prints them (hexadecimal, e.g. 0100007F for 127.0.0.1, 00000000 for every interface).
std::vector<std::string> listening_addresses(int port) {
  std::ifstream in("/proc/net/tcp");
  std::string line;
  std::getline(in, line);  // the column names
  std::vector<std::string> addresses;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string slot, local, remote, state;
    fields >> slot >> local >> remote >> state;
    const size_t colon = local.find(':');
    if (colon == std::string::npos || state != "0A") continue;  // 0A: LISTEN
    if (std::stoi(local.substr(colon + 1), nullptr, 16) == port) addresses.push_back(local.substr(0, colon));
  }
  return addresses;
}

// This machine's first IPv4 address other than loopback ("" when it has none).
std::string external_address() {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return "";
  std::string found;
  for (ifaddrs* a = list; a && found.empty(); a = a->ifa_next) {
    if (!a->ifa_addr || a->ifa_addr->sa_family != AF_INET) continue;
    const in_addr address = reinterpret_cast<sockaddr_in*>(a->ifa_addr)->sin_addr;
    if ((ntohl(address.s_addr) >> 24) == 127) continue;
    char text[INET_ADDRSTRLEN];
    inet_ntop(AF_INET, &address, text, sizeof(text));
    found = text;
  }
  freeifaddrs(list);
  return found;
}

// Whether a TCP connection to address:port is accepted.
bool connects(const std::string& address, int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  inet_pton(AF_INET, address.c_str(), &a.sin_addr);
  const bool ok = connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0;
  close(fd);
  return ok;
}

std::vector<uint8_t> bytes(const std::string& text) {
  return std::vector<uint8_t>(text.begin(), text.end());
}

// A frame as amt's rendezvous reads it: 4 bytes of length (big-endian), then the payload.
std::string frame(const std::string& payload) {
  std::string f;
  for (int i = 3; i >= 0; --i) f.push_back(static_cast<char>((payload.size() >> (8 * i)) & 0xff));
  return f + payload;
}

TEST(RendezvousStore, ListensOnTheNamedAddressOnly) {
  RendezvousStore store(store_options(0, true, kToken, milliseconds(5000)));
  const int port = store.port();
  ASSERT_GT(port, 0);
  // The finding: c10d's TCPStore listened on 00000000 (every interface) for tcp://127.0.0.1:PORT.
  EXPECT_EQ(listening_addresses(port), std::vector<std::string>{"0100007F"});
  const std::string external = external_address();
  if (!external.empty()) {
    EXPECT_FALSE(connects(external, port)) << "reached through " << external;
  }
  EXPECT_TRUE(connects("127.0.0.1", port));
}

TEST(RendezvousStore, AWrongTokenIsRefusedAndTheRightOneServed) {
  RendezvousStore server(store_options(0, true, kToken, milliseconds(5000)));
  const int port = server.port();
  const std::string refused = error_of([&] {
    RendezvousStore stranger(store_options(port, false, "fedcba9876543210fedcba9876543210", milliseconds(5000)));
  });
  EXPECT_EQ(refused, "rendezvous 127.0.0.1:" + std::to_string(port) +
                         ": the rendezvous refused this rank's token: every rank must present the same --dist-token "
                         "or AMT_DIST_TOKEN");
  // A raw client: the refusal, then the connection closed; nothing of the store is readable.
  {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
    ASSERT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0);
    const std::string magic = "amt-rendezvous-1", token = "wrong-token-wrong-token";
    std::string hello = frame(std::string("\0\0\0\x10", 4) + magic + std::string("\0\0\0\x17", 4) + token);
    ASSERT_EQ(send(fd, hello.data(), hello.size(), 0), static_cast<ssize_t>(hello.size()));
    std::string answer;
    char buffer[4096];
    for (ssize_t n; (n = recv(fd, buffer, sizeof(buffer), 0)) > 0;) answer.append(buffer, static_cast<size_t>(n));
    close(fd);  // recv returned 0: the server closed the connection
    ASSERT_GT(answer.size(), 5u);
    EXPECT_EQ(answer[4], 2) << "status: refused";
    EXPECT_NE(answer.find("refused this rank's token"), std::string::npos) << answer;
  }
  // The right token: two clients share the keys.
  RendezvousStore a(store_options(port, false, kToken, milliseconds(5000)));
  RendezvousStore b(store_options(port, false, kToken, milliseconds(5000)));
  a.set("k", bytes("value"));
  EXPECT_EQ(b.get("k"), bytes("value"));
  EXPECT_EQ(a.add("n", 3), 3);
  EXPECT_EQ(b.add("n", 4), 7);
  EXPECT_TRUE(b.check({"k", "n"}));
  EXPECT_FALSE(b.check({"k", "absent"}));
  EXPECT_EQ(a.compareSet("k", bytes("value"), bytes("new")), bytes("new"));
  EXPECT_EQ(a.compareSet("k", bytes("value"), bytes("other")), bytes("new"));
  EXPECT_EQ(a.getNumKeys(), 2);
  EXPECT_TRUE(b.deleteKey("k"));
  EXPECT_FALSE(b.deleteKey("k"));
  // A wait answered when another client sets the key.
  std::thread setter([&] {
    std::this_thread::sleep_for(milliseconds(200));
    server.set("later", bytes("x"));
  });
  b.wait({"later"});
  setter.join();
  EXPECT_EQ(b.get("later"), bytes("x"));
}

TEST(RendezvousStore, AWaitOnAMissingKeyEndsAtTheTimeoutWithAnError) {
  RendezvousStore store(store_options(0, true, kToken, milliseconds(1000)));
  const auto start = Clock::now();
  const std::string message = error_of([&] { store.get("missing"); });
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  EXPECT_EQ(message, "rendezvous 127.0.0.1:" + std::to_string(store.port()) + ": key 'missing': not set within 1 s");
  EXPECT_GE(seconds, 0.9);
  EXPECT_LT(seconds, 30.0);  // generous: the machine is loaded
  EXPECT_EQ(error_of([&] {
              store.wait({"a", "b"}, milliseconds(300));
            }),
            "rendezvous 127.0.0.1:" + std::to_string(store.port()) + ": keys 'a', 'b': not set within 0.3 s");
  // c10d's "no timeout" waits for the store's timeout, not forever.
  EXPECT_NE(error_of([&] { store.wait({"a"}, milliseconds(0)); }).find("not set within 1 s"), std::string::npos);
  // The store still answers after the timeouts.
  store.set("a", bytes("1"));
  EXPECT_EQ(store.get("a"), bytes("1"));
}

TEST(RendezvousStore, AClientWithoutAServerStopsAtTheTimeout) {
  const auto start = Clock::now();
  // Nobody listens on port 1.
  const std::string message =
      error_of([&] { RendezvousStore lost(store_options(1, false, kToken, milliseconds(500))); });
  EXPECT_EQ(message.rfind("rendezvous 127.0.0.1:1: not reached within 0.5 s (", 0), 0u) << message;
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - start).count(), 30.0);
}

TEST(RendezvousTokens, LoopbackHostsTokensAndTheLocalTokenFile) {
  for (const std::string host : {"localhost", "127.0.0.1", "127.1.2.3", "::1"}) EXPECT_TRUE(is_loopback_host(host));
  for (const std::string host : {"127.evil.example", "10.0.0.7", "node7", "0.0.0.0", "::"})
    EXPECT_FALSE(is_loopback_host(host)) << host;
  EXPECT_EQ(error_of([] { check_token(kToken, "--dist-token"); }), "");
  EXPECT_EQ(error_of([] { check_token("short", "AMT_DIST_TOKEN"); }),
            "AMT_DIST_TOKEN: expected a shared token of 16 to 256 printable characters without spaces (e.g. from "
            "`openssl rand -hex 32`), found 5 characters");
  EXPECT_NE(error_of([] { check_token("with spaces in the token", "--dist-token"); }).find("with spaces"),
            std::string::npos);
  const std::string a = generate_token(), b = generate_token();
  EXPECT_EQ(a.size(), 64u);
  EXPECT_NE(a, b);

  const fs::path home = test::temp_dir("rendezvous_home");
  setenv("HOME", home.c_str(), 1);
  const std::string path = local_token_path("127.0.0.1", 29500);
  EXPECT_EQ(path, (home / ".cache/amt/rendezvous-127.0.0.1-29500.token").string());
  write_local_token(path, a);
  EXPECT_EQ(read_local_token(path), a);
  struct stat st {};
  ASSERT_EQ(stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  ASSERT_EQ(stat((home / ".cache/amt").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0700u);
  // A token file others can read is not trusted.
  chmod(path.c_str(), 0644);
  EXPECT_NE(error_of([&] { read_local_token(path); }).find("not a file of this user's that only it reads"),
            std::string::npos);
  fs::remove(path);
  EXPECT_NE(error_of([&] { read_local_token(path); }).find("rank 0 writes it when it starts"), std::string::npos);
}

TEST(RendezvousTokens, ANonLoopbackRendezvousNeedsAToken) {
  const auto env = [](const char* name) -> const char* {
    return std::string(name) == "AMT_DIST_TOKEN" ? "abcdefghijklmnopqrstuvwxyz" : nullptr;
  };
  const auto none = [](const char*) -> const char* { return nullptr; };
  EXPECT_EQ(error_of([&] {
              resolve_distributed_options(DistributedOptions{2, 0, "tcp://10.0.0.7:29500", 300.0, ""}, none);
            }),
            "--dist-token: the rendezvous tcp://10.0.0.7:29500 is not on a loopback address, so every rank must "
            "present a shared token: give each rank the same --dist-token or AMT_DIST_TOKEN (16 to 256 characters, "
            "e.g. from `openssl rand -hex 32`)");
  EXPECT_EQ(resolve_distributed_options(DistributedOptions{2, 0, "tcp://10.0.0.7:29500", 300.0, ""}, env).token,
            "abcdefghijklmnopqrstuvwxyz");
  EXPECT_EQ(resolve_distributed_options(DistributedOptions{2, 0, "tcp://127.0.0.1:29500", 300.0, ""}, none).token, "");
  EXPECT_EQ(error_of([&] {
              resolve_distributed_options(DistributedOptions{2, 0, "tcp://10.0.0.7:29500", 300.0, "short"}, none);
            }).rfind("--dist-token: expected a shared token of 16 to 256", 0),
            0u);
}

// Two ranks joined on two threads at `rendezvous`; each thread's error ("" when none).
std::vector<std::string> join_two(const std::string& rendezvous, double timeout, int delay_rank0_ms,
                                  const std::function<void(int, DataParallelGroup&)>& f = {}) {
  std::vector<std::string> errors(2);
  std::vector<std::thread> threads;
  for (int rank : {1, 0}) {
    threads.emplace_back([&, rank] {
      if (rank == 0) std::this_thread::sleep_for(milliseconds(delay_rank0_ms));
      try {
        DataParallelGroup group(DistributedOptions{2, rank, rendezvous, timeout, ""});
        if (f) f(rank, group);
        group.barrier("the test");
      } catch (const std::exception& e) {
        errors[rank] = e.what();
      }
    });
  }
  for (auto& t : threads) t.join();
  return errors;
}

TEST(DataParallelRendezvous, ATcpRunOnLoopbackListensOnLoopbackWithAGeneratedToken) {
  const fs::path home = test::temp_dir("rendezvous_tcp_home");
  setenv("HOME", home.c_str(), 1);
  // A port the system has free.
  int port = 0;
  {
    RendezvousStore probe(store_options(0, true, kToken, milliseconds(2000)));
    port = probe.port();
  }
  std::vector<std::string> seen;
  bool token_file_seen = false;
  const auto errors = join_two("tcp://127.0.0.1:" + std::to_string(port), 20.0, 0, [&](int rank, DataParallelGroup&) {
    if (rank != 0) return;
    seen = listening_addresses(port);
    const fs::path token = home / ".cache/amt" / ("rendezvous-127.0.0.1-" + std::to_string(port) + ".token");
    token_file_seen = fs::exists(token);
  });
  EXPECT_EQ(errors, (std::vector<std::string>{"", ""}));
  EXPECT_EQ(seen, std::vector<std::string>{"0100007F"});
  EXPECT_TRUE(token_file_seen);
  // Rank 0 removes the token file when the run ends.
  EXPECT_TRUE(fs::is_empty(home / ".cache/amt"));
}

TEST(DataParallelRendezvous, AFileRendezvousOntoAUsersFileIsRefusedAndTheFileUnchanged) {
  const fs::path dir = test::temp_dir("rendezvous_users_file");
  const fs::path notes = dir / "notes.txt";
  const std::string text = "my notes\nthings to do\n";
  { std::ofstream(notes) << text; }
  const auto modified = fs::last_write_time(notes);
  const std::string rendezvous = "file://" + notes.string();
  for (int rank : {0, 1}) {
    const auto start = Clock::now();
    const std::string message = error_of([&] {
      DataParallelGroup group(DistributedOptions{2, rank, rendezvous, 30.0, ""});
    });
    EXPECT_EQ(message, "data-parallel run " + rendezvous + ", rank " + std::to_string(rank) +
                           " of 2: --rendezvous: " + notes.string() +
                           " is a file amt did not write, not a rendezvous amt made (its first line "
                           "would be 'amt data-parallel rendezvous 1'); amt leaves it as it is: give a path that does "
                           "not exist");
    // At once, not after the timeout.
    EXPECT_LT(std::chrono::duration<double>(Clock::now() - start).count(), 15.0);
  }
  EXPECT_EQ(test::read_file_bytes(notes), text);
  EXPECT_EQ(fs::last_write_time(notes), modified);
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  EXPECT_EQ(names, std::set<std::string>{"notes.txt"});
}

// The files a killed run leaves: the marker (no process holds its lock any more) and its store, holding
// the dead run's keys.
void leave_stale_run(const fs::path& path, const std::string& run_id) {
  { std::ofstream(path) << FileRendezvous::header() << "\nrun " << run_id << "\n"; }
  { std::ofstream(path.string() + ".run-" + run_id) << "stale keys of the killed run"; }
}

TEST(DataParallelRendezvous, AStaleFileStoreOfAKilledRunIsReplacedAndTheRunProceeds) {
  const fs::path dir = test::temp_dir("rendezvous_stale");
  const fs::path path = dir / "rendezvous";
  const std::string stale = "00112233445566778899aabbccddeeff";
  leave_stale_run(path, stale);
  // Rank 1 comes first and must wait past the stale marker for rank 0's new run, as after kill -9 and a rerun.
  std::vector<float> averaged(2);
  const auto errors = join_two("file://" + path.string(), 20.0, 700, [&](int rank, DataParallelGroup& group) {
    at::Tensor p = at::zeros({1}).requires_grad_();
    p.mutable_grad() = at::full({1}, rank == 0 ? 1.0f : 3.0f);
    std::vector<double> values;
    group.average_gradients({p}, values, 0);
    averaged[rank] = p.grad()[0].item<float>();
  });
  EXPECT_EQ(errors, (std::vector<std::string>{"", ""}));
  EXPECT_EQ(averaged, (std::vector<float>{2.0f, 2.0f}));
  // Neither the stale files nor the run's own are left.
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  EXPECT_EQ(names, std::set<std::string>{});
}

TEST(DataParallelRendezvous, ARankFacingOnlyAStaleMarkerStopsAtTheTimeoutNamingIt) {
  const fs::path dir = test::temp_dir("rendezvous_stale_alone");
  const fs::path path = dir / "rendezvous";
  const std::string stale = "00112233445566778899aabbccddeeff";
  leave_stale_run(path, stale);
  const auto start = Clock::now();
  const std::string message = error_of([&] {
    DataParallelGroup group(DistributedOptions{2, 1, "file://" + path.string(), 1.0, ""});
  });
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  EXPECT_EQ(message, "data-parallel run file://" + path.string() + ", rank 1 of 2: --rendezvous: no run started at " +
                         path.string() + " within 1 s (--dist-timeout): it names the run " + stale +
                         " of an earlier run whose rank 0 is gone (the next rank 0 replaces it); start rank 0 with "
                         "the same --rendezvous");
  EXPECT_GE(seconds, 0.9);
  EXPECT_LT(seconds, 30.0);
  // A rank other than 0 never touches the files.
  EXPECT_TRUE(fs::exists(path.string() + ".run-" + stale));
}

TEST(DataParallelRendezvous, ASecondRankZeroRefusesARendezvousInUse) {
  const fs::path dir = test::temp_dir("rendezvous_in_use");
  const std::string path = (dir / "rendezvous").string();
  std::string message;
  {
    FileRendezvous first(path, true, milliseconds(1000));
    EXPECT_TRUE(fs::exists(first.store_path()));
    EXPECT_EQ(first.store_path(), path + ".run-" + first.run_id());
    // Another rank finds the live run at once.
    FileRendezvous other(path, false, milliseconds(1000));
    EXPECT_EQ(other.run_id(), first.run_id());
    message = error_of([&] { FileRendezvous second(path, true, milliseconds(1000)); });
    EXPECT_EQ(message, "--rendezvous: " + path + " is in use by the run " + first.run_id() +
                           ", whose rank 0 is alive; stop that run or give this one another path");
    fs::remove(first.store_path());
  }
  EXPECT_FALSE(fs::exists(path));  // rank 0 removes its marker when it leaves
}

}  // namespace
}  // namespace amt
