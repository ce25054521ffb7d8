// frontier-view's failure messages and its one-frame output files.
#include "viewer/outputs.h"

#include "src/io/image.h"

#include <fmt/core.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace frontier {

int fail(const Status& s) {
  std::fprintf(stderr, "frontier-view: %s\n", s.to_string().c_str());
  return 1;
}

int bad_option(const std::string& message) {
  std::fprintf(stderr, "frontier-view: %s\n", message.c_str());
  return 2;
}

Status write_json(const std::string& path, const nlohmann::json& j) {
  std::ofstream out(path);
  out << j.dump(2) << "\n";
  return out ? Status::ok() : Status::io_error(path + ": cannot write");
}

std::string frame_file(const std::string& dir, size_t frame, const char* ext) {
  return fmt::format("{}/frame_{:05d}.{}", dir, frame, ext);
}

Status make_output_dir(const std::string& option, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Status::io_error(fmt::format("{} {}: cannot create the directory: {}", option, dir, ec.message()));
  if (!std::filesystem::is_directory(dir, ec))
    return Status::io_error(fmt::format("{} {}: exists and is not a directory", option, dir));
  return Status::ok();
}

int write_frame_files(const ViewerOptions& o, int width, int height, const Frame& frame) {
  if (!o.png_path.empty()) {
    if (Status s = write_png(o.png_path, width, height, frame.colors); !s) return fail(s);
  }
  if (!o.ids_path.empty()) {
    if (Status s = write_ids(o.ids_path, frame.ids); !s) return fail(s);
  }
  if (!o.stats_path.empty()) {
    if (Status s = write_json(o.stats_path, frame.stats); !s) return fail(s);
  }
  return 0;
}

}  // namespace frontier
