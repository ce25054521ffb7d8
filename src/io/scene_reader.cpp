// open_scene_reader: picks the format reader by file extension; helpers shared by the readers.
#include "src/io/read_formats.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>

#include <sys/stat.h>

namespace frontier {

Result<std::unique_ptr<SceneReader>> open_scene_reader(const std::string& path) {
  // What is not a file is told as such before its extension is looked at.
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    std::string msg = fmt::format("{}: cannot open: {}", path, std::strerror(err));
    return err == ENOENT ? Status::not_found(std::move(msg)) : Status::io_error(std::move(msg));
  }
  if (S_ISDIR(st.st_mode)) return Status::io_error(fmt::format("{}: is a directory, not a model file", path));
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  std::string ext;
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) {
    ext = path.substr(dot + 1);
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  }
  if (ext == "nff") return open_nff_reader(path);
  if (ext == "ply") return open_ply_reader(path);
  if (ext == "obj") return open_obj_reader(path);
  if (ext == "off") return open_off_reader(path);
  if (ext == "stl") return open_stl_reader(path);
  return Status::unsupported(
      fmt::format("{}: unknown model format '.{}' (expected .nff, .ply, .obj, .off or .stl)", path, ext));
}

Status byte_error(const std::string& path, uint64_t offset, std::string_view message) {
  return Status::corruption(fmt::format("{}: byte {}: {}", path, offset, message));
}

std::string trailing_data_warning(const std::string& path, uint64_t offset, uint64_t bytes) {
  return fmt::format("{}: byte {}: {} bytes after the last record, ignored", path, offset, bytes);
}

void FormatReader::warn_trailing_text(TextTokenizer& tok) {
  const uint64_t at = tok.skip_space();
  if (at < tok.size()) warn(trailing_data_warning(tok.path(), at, tok.size() - at));
}

std::string check_polygon_size(int64_t count, std::string_view what) {
  if (count < 3) return fmt::format("{} has {} vertices (needs at least 3)", what, count);
  if (count > kMaxPolygonVertices) {
    return fmt::format("{} has {} vertices (limit {})", what, count, kMaxPolygonVertices);
  }
  return {};
}

}  // namespace frontier
