// Where the model writers (PlyWriter, NffWriter) put a file's bytes until they finish, so that
// a failed or interrupted write never leaves a partial file under the name asked for.
#pragma once

#include <string>

#include <sys/stat.h>

namespace frontier {

// PATH.tmp, which the writer renames over PATH when it finishes, when PATH is a regular file or
// does not exist yet; empty for anything else (a device such as /dev/null, a FIFO), which the
// writer writes in place.
inline std::string staging_path(const std::string& path) {
  struct stat st {};
  const bool exists = ::stat(path.c_str(), &st) == 0;
  return !exists || S_ISREG(st.st_mode) ? path + ".tmp" : std::string();
}

}  // namespace frontier
