// Image output: 8-bit RGB PNG (libpng) and raw id images.
#pragma once

#include "src/core/sample_buffer.h"
#include "src/core/status.h"

#include <cstdint>
#include <string>
#include <vector>

namespace frontier {

// Writes colours (clamped to [0,1]) as an 8-bit RGB PNG.
Status write_png(const std::string& path, int width, int height, const std::vector<Rgb>& pixels);
// Reads an 8-bit RGB(A) PNG back (tests, image comparison).
Status read_png(const std::string& path, int& width, int& height, std::vector<Rgb>& pixels);
// Writes uint32 ids, little-endian, row-major (the --ids format).
Status write_ids(const std::string& path, const std::vector<uint32_t>& ids);

}  // namespace frontier
