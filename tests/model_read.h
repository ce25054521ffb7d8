// Reading a model file to its end through the pull interface (src/io/scene_reader.h), for the
// reader tests: the primitives that came out, the status that ended the read, and what the
// reader declared and warned about. Progress never passes the file size.
#pragma once

#include "src/io/scene_reader.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace frontier::testing {

struct ModelRead {
  Status status;
  std::vector<InputPrimitive> prims;
  SceneHeader header;
  int64_t declared = -1;
  bool binary = false;
  std::vector<std::string> warnings;
};

inline ModelRead read_model(const std::string& path) {
  ModelRead r;
  auto reader = open_scene_reader(path);
  if (!reader) {
    r.status = reader.status();
    return r;
  }
  r.declared = (*reader)->declared_primitives();
  r.binary = (*reader)->binary();
  InputPrimitive p;
  for (;;) {
    bool end = false;
    r.status = (*reader)->next(p, end);
    if (!r.status || end) break;
    r.prims.push_back(p);
  }
  EXPECT_LE((*reader)->bytes_read(), (*reader)->bytes_total());
  r.header = (*reader)->header();
  r.warnings = (*reader)->warnings();
  return r;
}

}  // namespace frontier::testing
