// What frontier-view writes, shared by its modes: the message and exit code of a failure
// (1: bad input, naming the file and line or page; 2: bad options), JSON files, one frame's
// --png, --ids and --stats files, and the per-frame files' names and directories.
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

// DIR/frame_NNNNN.EXT, the name of frame `frame` (from 0) in --png-dir and --ids-dir.
std::string frame_file(const std::string& dir, size_t frame, const char* ext);
// Creates the output directory `dir` of `option` (--png-dir, --ids-dir) with its parents.
// IoError naming the option and the directory when it cannot be created or is not a directory.
Status make_output_dir(const std::string& option, const std::string& dir);

// Writes the files the options ask for: --png (frame.colors), --ids (frame.ids), --stats
// (frame.stats), in that order. Returns 0, or fail()'s code for the first that cannot be written.
int write_frame_files(const ViewerOptions& o, int width, int height, const Frame& frame);

}  // namespace frontier
