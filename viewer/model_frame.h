// frontier-view on a model file (or a store decoded whole, --in-memory): one complete frame
// with the method the options pick from the method table (viewer/methods.h).
#pragma once

#include "viewer/options.h"

namespace frontier {

// Loads the model (`store`: SCENE is a store, decoded into memory), builds its k-d tree, renders
// one frame from the model's camera (or one framing it) with the picked method, prints the
// method's line on stderr and writes --png, --ids and --stats. Returns the exit code.
int render_model(const ViewerOptions& o, bool store);

}  // namespace frontier
