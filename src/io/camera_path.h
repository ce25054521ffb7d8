// Camera paths (.cam files): the walkthroughs that frontier-gen writes and the viewer replays.
//
// Format (text, one frame per line, documented in data_gen/README.md):
//
//   # comment lines start with '#'; blank lines are ignored
//   ex ey ez  lx ly lz  ux uy uz  vfov_deg
//
// eye, look-at point and up vector in model coordinates, then the full vertical field of view
// in degrees. Numbers are separated by spaces or tabs. The writer prints the shortest text
// that reads back to the same double, so write -> read is exact.
//
// A frame is valid when every number is finite, 0 < vfov_deg < 180, the look-at point differs
// from the eye, and the up vector is non-zero and not parallel to the viewing direction.
// Readers reject anything else with a Status naming the file and the line.
#pragma once

#include "src/core/scene.h"
#include "src/core/status.h"

#include <string>
#include <string_view>
#include <vector>

namespace frontier {

// Empty string when `cam` is a valid frame, else what is wrong with it.
std::string camera_frame_problem(const Camera& cam);

// The text of a .cam file: `comments` as leading '#' lines, then one line per frame.
std::string format_camera_path(const std::vector<Camera>& frames,
                               const std::vector<std::string>& comments = {});

// Writes a .cam file ("-" = stdout). Fails with InvalidArgument for an invalid frame (naming
// its index) and IoError when the file cannot be written.
Status write_camera_path(const std::string& path, const std::vector<Camera>& frames,
                         const std::vector<std::string>& comments = {});

// Parses .cam text; `name` prefixes error messages ("NAME: line 7: ..."). Only eye, look_at,
// up and vfov_deg are set in the result; other Camera fields keep their defaults.
Result<std::vector<Camera>> parse_camera_path(std::string_view text, const std::string& name);

// Reads a .cam file. NotFound when it cannot be opened; Corruption for malformed lines.
Result<std::vector<Camera>> read_camera_path(const std::string& path);

}  // namespace frontier
