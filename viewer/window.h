// The interactive window of frontier-view (GLFW): a walkthrough of a store, rendered by the
// out-of-core frustum caster (src/walk/walkthrough.h) and shown as a texture, with a HUD.
#pragma once

#include "src/core/scene.h"
#include "src/walk/walkthrough.h"

#include <functional>
#include <string>
#include <vector>

namespace frontier {

class Walker;  // src/walk/walker.h (walk mode), may be null

struct WindowOptions {
  Camera start;                       // initial camera
  int frames = 0;                     // > 0: close after this many frames (scripted runs, tests)
  std::vector<Camera> path;           // non-empty: replay this path (one camera per frame) instead of input
  std::string screenshot;             // non-empty: write the last displayed frame as PNG here on exit
  std::string report;                 // non-empty: write one JSON line per frame (FrameReport) here
  std::string ids_dir;                // non-empty (with a path): write each frame's ids as DIR/frame_NNNNN.ids
  double speed = 1.0;                 // metres per second at start (mouse wheel / +,- change it)
  bool walk_available = false;        // the store declares walk mode (Walker given)
  bool start_walking = false;         // start in walk mode (needs a Walker); F toggles
  FrameBudget budget;                 // the Walkthrough's budget at open() (shown; P toggles it, see window_input.cpp)
  // Scripted input for tests: called once per frame with the frame index; may return GLFW key
  // codes to treat as pressed during that frame.
  std::function<std::vector<int>(int)> script;
};

// Opens the window and runs until it is closed (Esc or the close button) or `frames` frames
// are shown. Returns 0 on success, 1 if the window cannot be created (no display: the message
// says to use --headless), with the message on stderr.
int run_window(Walkthrough& walk, const WindowOptions& options, Walker* walker);

}  // namespace frontier
