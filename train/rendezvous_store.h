#pragma once
// Where the ranks of a data-parallel run meet (train/distributed.h, issue 34): amt's own key-value store
// for a tcp:// rendezvous and the marker of a file:// one.
//
// The tcp:// store is written by hand because c10d::TCPStore as Debian's LibTorch 1.13 ships it listens on
// every network interface (it has no bind address: tcp://127.0.0.1:PORT was reachable from the machine's
// external address) and lets anyone who connects read and write the run's keys (no authentication). This
// one listens on the address the rendezvous names only, and a client presents the run's shared token
// before anything else. Gloo reaches it through the c10d::Store interface, as it reached TCPStore.
//
// The file:// marker exists because c10d::FileStore 1.13 reads any file as a store: on a user's file it
// spins at EOF and appends to it, and the file of a killed run holds that run's stale addresses, which a
// rerun waits on. amt's marker file says "this is an amt rendezvous" in its first line and names the
// current run; the store of that run is a file of its own beside it.
#include <torch/csrc/distributed/c10d/Store.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "data_tools/geometry/error.h"

namespace amt {

/// A refusal by the rendezvous (a wrong token, a server that is not amt's): not worth a retry, and its
/// message is complete.
class RendezvousRefused : public Error {
 public:
  using Error::Error;
};

/// Whether `host` names this machine's loopback interface: "localhost", an IPv4 address 127.x.y.z or ::1
/// (a name merely starting with "127." is not).
bool is_loopback_host(const std::string& host);

/// Checks a shared token given by `source` (--dist-token or AMT_DIST_TOKEN): 16 to 256 printable ASCII
/// characters without spaces. Throws amt::Error naming `source` (never the token) otherwise.
void check_token(const std::string& token, const std::string& source);

/// A new random token (64 hexadecimal digits from the system's random source).
std::string generate_token();

/// Where rank 0 of a loopback tcp:// rendezvous without a given token writes the token it generates, and
/// the other local ranks read it: ~/.cache/amt/rendezvous-HOST-PORT.token (the folder mode 0700, the file
/// mode 0600, so only this user reads it).
std::string local_token_path(const std::string& host, int port);
/// Writes `token` to `path` (mode 0600, created anew and renamed into place). Throws amt::Error naming the path.
void write_local_token(const std::string& path, const std::string& token);
/// Reads the token at `path`; throws amt::Error naming the path when it is missing, not a regular file of
/// this user, or readable by others.
std::string read_local_token(const std::string& path);

/// amt's tcp:// rendezvous store. Rank 0 runs the server on a thread of its own and, like every rank, is
/// a client of it over one connection.
class RendezvousStore : public c10d::Store {
 public:
  struct Options {
    /// The rendezvous's host (name or address) and port; the server binds to the address `host` resolves
    /// to (port 0: one the system chooses, see port()).
    std::string host;
    int port = 0;
    /// Rank 0: run the server.
    bool serve = false;
    /// The server's bound on simultaneous connections (the ranks and anyone who knocks; a connection that
    /// has not presented a token within 10 s is closed).
    int max_connections = 64;
    /// The run's token. A client without one calls `read_token` once connected (a local rank reads the
    /// token rank 0 wrote, which rank 0 writes before it listens).
    std::string token;
    std::function<std::string()> read_token;
    /// Server: called once the address is bound and before connections are accepted.
    std::function<void(int port)> bound;
    /// Bound on connecting (rank 0 may start later) and on every exchange and wait.
    std::chrono::milliseconds timeout{300000};
  };

  /// Starts the server (serve) and connects to it. Throws RendezvousRefused when the server refuses the
  /// token or is not amt's, amt::Error when the address cannot be bound or the server not reached in time.
  explicit RendezvousStore(Options options);
  ~RendezvousStore() override;

  void set(const std::string& key, const std::vector<uint8_t>& value) override;
  std::vector<uint8_t> compareSet(const std::string& key, const std::vector<uint8_t>& expected,
                                  const std::vector<uint8_t>& desired) override;
  /// Waits for the key up to the store's timeout.
  std::vector<uint8_t> get(const std::string& key) override;
  int64_t add(const std::string& key, int64_t value) override;
  bool deleteKey(const std::string& key) override;
  bool check(const std::vector<std::string>& keys) override;
  int64_t getNumKeys() override;
  void wait(const std::vector<std::string>& keys) override;
  /// A timeout of zero (c10d's "no timeout") waits for the store's timeout: every wait ends.
  void wait(const std::vector<std::string>& keys, const std::chrono::milliseconds& timeout) override;

  /// The port the server listens on (the rendezvous's, or the system's choice for port 0).
  int port() const;

 private:
  struct Server;
  struct Client;
  std::unique_ptr<Server> server_;
  std::unique_ptr<Client> client_;
};

/// The marker of a file:// rendezvous at `path`: its first line is "amt data-parallel rendezvous 1", the
/// second "run <id>" names the current run, whose c10d::FileStore is the file "<path>.run-<id>". Rank 0
/// holds a lock on the marker (an open file description lock, which the system releases when the process
/// ends, even by kill -9) for as long as its run lives: a marker nobody holds is a stale one.
class FileRendezvous {
 public:
  /// Rank 0 (`first`): refuses an existing `path` that is not amt's marker (left as it is) or whose run is
  /// alive; otherwise starts a new run: a fresh store file under a new run id, the marker replaced in one
  /// step and held, the stores of earlier runs beside it removed. Another rank: waits, up to `timeout`, for a
  /// marker whose run is alive (a stale one is waited past, never joined); refuses a file that is not amt's
  /// at once. Throws amt::Error (a complete message about `path`) on a refusal or at the timeout.
  FileRendezvous(const std::string& path, bool first, std::chrono::milliseconds timeout);
  /// Rank 0: removes the marker (while still its own) and releases it.
  ~FileRendezvous();
  FileRendezvous(const FileRendezvous&) = delete;
  FileRendezvous& operator=(const FileRendezvous&) = delete;

  const std::string& run_id() const { return run_id_; }
  /// The run's c10d::FileStore file.
  const std::string& store_path() const { return store_path_; }

  /// The marker's first line.
  static const char* header();

 private:
  std::string path_, run_id_, store_path_;
  int fd_ = -1;  // rank 0: the marker, locked
};

}  // namespace amt
