// `amt view FILES...`: a local web viewer. Serves the repository's viewer page (viewer/, three.js from
// npm) and the given GLBs on 127.0.0.1 with cpp-httplib (Debian's libcpp-httplib-dev) and prints the
// URL; or serves a viewer folder that `amt animate --html` / `amt eval --viewer` wrote. Runs until
// Ctrl-C (SIGINT / SIGTERM end the process, app/main.cpp).
#include <httplib.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "app/commands.h"
#include "app/repository.h"
#include "data_tools/geometry/error.h"
#include "data_tools/formats/input_file.h"
#include "data_tools/formats/viewer_folder.h"

namespace amt::app {
namespace {

namespace fs = std::filesystem;

struct ViewCommand {
  std::vector<std::string> files;
  std::string title;
  int port = 8765;
};

// Checks that `path` is a GLB (binary glTF 2.0 header); what is inside is the page's to read and report.
void check_glb_header(const std::string& path) {
  const uint64_t size = check_input_file(path, "a GLB file (binary glTF)");
  AMT_CHECK(size >= 12, path, ": header: expected a 12-byte GLB header, found ", size, " bytes");
  std::ifstream in(path, std::ios::binary);
  char header[12] = {};
  in.read(header, sizeof(header));
  AMT_CHECK(in.gcount() == 12, path, ": header: expected 12 bytes, found an error reading them");
  uint32_t version = 0;
  std::memcpy(&version, header + 4, 4);
  AMT_CHECK(std::memcmp(header, "glTF", 4) == 0, path,
            ": header: expected the GLB magic 'glTF' (amt view plays .glb files), found other bytes");
  AMT_CHECK(version == 2, path, ": header: expected glTF version 2, found ", version);
}

// The role the page gives a file, from its name: "ground_truth" / "gt", "skinning", else "prediction".
std::string role_of(const std::string& stem) {
  const bool ends_gt = stem.size() > 3 && stem.compare(stem.size() - 3, 3, "_gt") == 0;
  if (stem.find("ground_truth") != std::string::npos || stem == "gt" || stem.rfind("gt_", 0) == 0 || ends_gt)
    return "ground_truth";
  if (stem.find("skinning") != std::string::npos) return "skinning";
  return "prediction";
}

// The content type of a served file, from its extension.
const char* content_type(const fs::path& path) {
  const std::string e = path.extension().string();
  if (e == ".html") return "text/html";
  if (e == ".js" || e == ".mjs") return "text/javascript";
  if (e == ".json") return "application/json";
  if (e == ".glb") return "model/gltf-binary";
  if (e == ".png") return "image/png";
  if (e == ".css") return "text/css";
  return "application/octet-stream";
}

// Streams the regular file `path` in 64 KB pieces (never the whole file in memory); cpp-httplib answers a
// single byte range from the provider. 404 for anything else.
void serve_file(httplib::Response& response, const std::string& path, const char* type) {
  std::error_code error;
  const fs::file_status status = fs::status(path, error);
  if (error || !fs::is_regular_file(status)) {
    response.status = 404;
    return;
  }
  const uintmax_t size = fs::file_size(path, error);
  if (error) {
    response.status = 404;
    return;
  }
  auto in = std::make_shared<std::ifstream>(path, std::ios::binary);
  response.set_content_provider(size, type, [in](size_t offset, size_t length, httplib::DataSink& sink) {
    std::vector<char> buffer(std::min<size_t>(length, 1 << 16));
    in->clear();
    in->seekg(static_cast<std::streamoff>(offset));
    in->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const std::streamsize n = in->gcount();
    return n > 0 && sink.write(buffer.data(), static_cast<size_t>(n));
  });
}

// The file of a viewer folder (real path `root`, canonical) that request path `relative` names, or "" when it
// may not be served: a component that is empty, "." or "..", or starts with a dot (dotfiles), or a path whose
// real location (symbolic links followed) is not a regular file inside the folder. cpp-httplib has already
// refused paths that climb out with "..", but a link inside the folder can point anywhere; a folder someone
// sends you must not read your files through it.
std::string folder_file(const fs::path& root, const std::string& relative) {
  const std::string name = relative.empty() ? "index.html" : relative;
  size_t start = 0;
  while (start <= name.size()) {
    const size_t end = std::min(name.find('/', start), name.size());
    const std::string part = name.substr(start, end - start);
    if (part.empty() || part[0] == '.') return "";
    start = end + 1;
  }
  std::error_code error;
  const fs::path real = fs::canonical(root / name, error);
  if (error || !fs::is_regular_file(real, error)) return "";
  const std::string inside = root.string() + "/";
  if (real.string().compare(0, inside.size(), inside) != 0) return "";
  return real.string();
}

// Refuses, before any handler, what a page on 127.0.0.1 must never answer: a Host other than 127.0.0.1 or
// localhost at the served port (DNS rebinding: a page of another site whose name resolves here), and a Range
// of more than one part (a few bytes of request asking for the file many times over).
httplib::Server::HandlerResponse guard(const httplib::Request& request, httplib::Response& response, int port) {
  const std::string host = request.get_header_value("Host");
  const std::string at = ":" + std::to_string(port);
  if (host != "127.0.0.1" + at && host != "localhost" + at) {
    response.status = 403;
    response.set_content("amt view answers only Host 127.0.0.1" + at + " or localhost" + at + "\n", "text/plain");
    return httplib::Server::HandlerResponse::Handled;
  }
  if (request.get_header_value("Range").find(',') != std::string::npos) {
    response.status = 416;
    response.set_content("amt view answers one byte range per request\n", "text/plain");
    return httplib::Server::HandlerResponse::Handled;
  }
  return httplib::Server::HandlerResponse::Unhandled;
}

void run(const ViewCommand& command) {
  httplib::Server server;
  std::string what;
  std::error_code error;
  if (command.files.size() == 1 && fs::is_directory(command.files[0], error)) {
    // A viewer folder: served as it is.
    const std::string dir = command.files[0];
    AMT_CHECK(fs::is_regular_file(fs::path(dir) / kViewerManifestName, error), dir,
              ": expected a viewer folder (written by amt animate --html or amt eval --viewer, with ",
              kViewerManifestName, "), found a folder without one");
    check_viewer_folder(dir, /*to_write=*/false);
    const fs::path root = fs::canonical(dir, error);
    AMT_CHECK(!error, dir, ": expected a folder to serve, found an error resolving it: ", error.message());
    server.Get(R"(/(.*))", [root](const httplib::Request& request, httplib::Response& response) {
      const std::string path = folder_file(root, request.matches[1].str());
      if (path.empty()) {
        response.status = 404;
        return;
      }
      serve_file(response, path, content_type(path));
    });
    what = dir;
  } else {
    // Files: the repository's page and three.js, a manifest of one group, the files under /files/<k>/.
    const std::string viewer_dir = find_repository_folder("viewer");
    AMT_CHECK(!viewer_dir.empty(), "amt view: expected the repository's viewer/ folder above the amt program or in "
              "the current folder, found none: run amt from a checkout");
    ViewerManifest manifest;
    manifest.title = command.title;
    ViewerGroup group;
    std::vector<std::string> paths;
    for (const std::string& file : command.files) {
      AMT_CHECK(!fs::is_directory(file, error), file,
                ": expected GLB files or one viewer folder, found a folder among several arguments");
      check_glb_header(file);
      const std::string url = "files/" + std::to_string(paths.size()) + "/" + fs::path(file).filename().string();
      paths.push_back(file);
      const std::string stem = fs::path(file).stem().string();
      group.items.push_back({url, stem, role_of(stem)});
    }
    manifest.groups.push_back(group);
    const std::string manifest_json = viewer_manifest_json(manifest);
    for (const auto& [relative, source] : viewer_page_files(viewer_dir)) {
      const std::string type = relative.size() > 3 && relative.compare(relative.size() - 3, 3, ".js") == 0
                                   ? "text/javascript"
                                   : relative.size() > 5 && relative.compare(relative.size() - 5, 5, ".html") == 0
                                         ? "text/html"
                                         : "text/plain";
      const std::string path = source;
      server.Get("/" + relative, [path, type](const httplib::Request&, httplib::Response& response) {
        serve_file(response, path, type.c_str());
      });
      if (relative == "index.html") {
        server.Get("/", [path](const httplib::Request&, httplib::Response& response) {
          serve_file(response, path, "text/html");
        });
      }
    }
    server.Get(std::string("/") + kViewerManifestName,
               [manifest_json](const httplib::Request&, httplib::Response& response) {
                 response.set_content(manifest_json, "application/json");
               });
    server.Get(R"(/files/(\d+)/[^/]+)", [paths](const httplib::Request& request, httplib::Response& response) {
      const size_t k = std::stoul(request.matches[1].str());
      if (k >= paths.size()) {
        response.status = 404;
        return;
      }
      serve_file(response, paths[k], "model/gltf-binary");
    });
    what = std::to_string(paths.size()) + " file" + (paths.size() == 1 ? "" : "s");
  }
  const char* host = "127.0.0.1";
  int port = command.port;
  // Every request names this host and port; a request whose headers are not in within 5 s is dropped, so that a
  // few half-sent requests cannot hold the server's threads.
  server.set_pre_routing_handler([&port](const httplib::Request& request, httplib::Response& response) {
    return guard(request, response, port);
  });
  server.set_read_timeout(5, 0);
  server.set_keep_alive_timeout(5);
  if (port == 0) {
    port = server.bind_to_any_port(host);
    AMT_CHECK(port > 0, "--port 0: expected a free port on ", host, ", found none");
  } else {
    AMT_CHECK(server.bind_to_port(host, port), "--port ", port, ": expected a free port on ", host,
              ", found it in use or not allowed (pass another --port, or --port 0 for any free one)");
  }
  std::cout << "amt view: serving " << what << " at http://" << host << ":" << port << "/ (Ctrl-C stops)"
            << std::endl;
  AMT_CHECK(server.listen_after_bind(), "amt view: the server on ", host, ":", port, " stopped with an error");
}

}  // namespace

void add_view_command(CLI::App& app) {
  auto command = std::make_shared<ViewCommand>();
  auto* view = app.add_subcommand(
      "view", "A local web viewer on 127.0.0.1: plays GLBs side by side (prediction, ground truth, skinning), or a "
              "folder written by amt animate --html / amt eval --viewer");
  view->add_option("FILES", command->files,
                   "GLB files to play side by side (a name containing ground_truth is the reference of the PMD_a "
                   "readout; one containing skinning is labelled so), or one viewer folder")
      ->required();
  view->add_option("--port", command->port, "Port on 127.0.0.1 (0: any free port)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  view->add_option("--title", command->title, "Title shown on the page");
  add_threads_option(*view);
  view->callback([command] { run(*command); });
}

}  // namespace amt::app
