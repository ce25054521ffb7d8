// What frontier-view writes, shared by its modes: the message and exit code of a failure
// (1: bad input, naming the file and line or page; 2: bad options), JSON files, and one frame's
// --png, --ids and --stats files.
#pragma once

#include "src/core/status.h"
#include "src/engine/frame_renderer.h"
#include "viewer/options.h"

#include <nlohmann/json.hpp>

#include <string>

namespace frontier {

// Prints "frontier-view: <status>" on stderr; returns exit code 1.
int fail(const Status& s);
// Prints "frontier-view: <message>" on stderr; returns exit code 2.
int bad_option(const std::string& message);

// Writes `j` (indented) to `path`: the --stats and --bsp-stats files.
Status write_json(const std::string& path, const nlohmann::json& j);

// Writes the files the options ask for: --png (frame.colors), --ids (frame.ids), --stats
// (frame.stats), in that order. Returns 0, or fail()'s code for the first that cannot be written.
int write_frame_files(const ViewerOptions& o, int width, int height, const Frame& frame);

}  // namespace frontier
