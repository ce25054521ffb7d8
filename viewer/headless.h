// frontier-view on a store without a window: one complete frame from the store's camera, or a
// walk along a camera path with one JSON report line per frame and a summary.
#pragma once

#include "src/core/scene.h"
#include "src/walk/walkthrough.h"
#include "viewer/options.h"

namespace frontier {

// One complete frame of a store from `camera`, with the deferred effects the scene declares
// (shadows; Walkthrough::still_frame): a line on stderr (and one more when it thrashed), then
// --ids-dir's frame_00000.ids, --png, --ids, --stats. Returns the exit code.
int store_frame(const ViewerOptions& o, Walkthrough& walk, const Camera& camera);

// The walk along --path (or `start` alone) for --frames frames: --report's lines (FrameReport
// per frame, then {"summary": ...}), every --png-every'th frame and the last as PNG into
// --png-dir, every frame's ids into --ids-dir, with --walk the walker's collision and gravity, and the summary on stderr (with one
// line more when frames thrashed: the largest frame's working set and the --cache it needs).
// Returns the exit code.
int walk_headless(const ViewerOptions& o, Walkthrough& walk, const Camera& start);

}  // namespace frontier
