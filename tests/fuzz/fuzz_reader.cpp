// libFuzzer target for one scene reader (the format is fixed at build time by FUZZ_EXTENSION):
// the input bytes become a file, which is read to the end through the pull interface and
// then through load_scene. Any crash, leak, sanitizer report or hang is a finding; an error
// Status is the expected outcome for garbage.
#include "src/core/scene.h"
#include "src/io/load_scene.h"
#include "src/io/scene_reader.h"

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>
#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = "/tmp/frontier_fuzz_" + std::to_string(getpid()) + FUZZ_EXTENSION;
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return 0;
  std::fwrite(data, 1, size, f);
  std::fclose(f);
  auto reader = frontier::open_scene_reader(path);
  if (reader.is_ok()) {
    frontier::InputPrimitive prim;
    bool end = false;
    for (int i = 0; i < 100000; ++i) {
      if (!(*reader)->next(prim, end).is_ok() || end) break;
    }
  }
  frontier::Scene scene;
  std::vector<std::string> warnings;  // kept, not printed
  (void)frontier::load_scene(path, scene, &warnings);
  return 0;
}
