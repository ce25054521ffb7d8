// The raw body of a cell page (store/FORMAT.md "Raw body"): a Scene's primitives bit for bit —
// counts, the per-primitive kind, index, source and material streams, then every primitive's
// doubles. The raw codec's whole payload is one; the Draco codec stores its non-triangle
// primitives in one.
//
// write_raw_body is deterministic. read_raw_body is safe on untrusted bytes: it caps every
// count by the bytes left before it allocates, and reports damage as Corruption naming the codec
// and the byte offset.
#pragma once

#include "src/core/byte_io.h"
#include "src/core/scene.h"
#include "src/core/status.h"

#include <string_view>

namespace frontier::cell_page {

// REQUIRES: s passed the dispatcher's check_scene (indices in range, clip counts in range).
void write_raw_body(GeometryWriter& w, const Scene& s);

// Appends the primitives of a raw body to `out`, whose per-kind arrays may already hold
// elements (the Draco codec's triangles; the body's indices are shifted past them). The Draco
// codec's body must hold no triangles (`triangles_allowed` false). Leaves `r` after the body.
// `codec` names the codec in messages.
Status read_raw_body(GeometryReader& r, std::string_view codec, bool triangles_allowed, Scene& out);

}  // namespace frontier::cell_page
