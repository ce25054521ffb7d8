// Parallel, order-preserving piece pipeline into PlyWriter (see header).
#include "data_gen/piece_stream.h"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/parallel_reduce.h>

#include <atomic>
#include <memory>
#include <mutex>

namespace frontier::gen {

MeshCounts count_pieces(uint64_t piece_count, const PieceFunction& piece,
                        const PlyVertexLayout& layout) {
  return tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, piece_count), MeshCounts{},
      [&](const tbb::blocked_range<uint64_t>& r, MeshCounts acc) {
        for (uint64_t i = r.begin(); i != r.end(); ++i) {
          MeshBuilder counter(nullptr, layout);
          piece(i, counter);
          acc.vertices += counter.vertices();
          acc.triangles += counter.triangles();
        }
        return acc;
      },
      [](MeshCounts a, const MeshCounts& b) {
        a.vertices += b.vertices;
        a.triangles += b.triangles;
        return a;
      });
}

namespace {

struct Token {
  uint64_t index = 0;
  MeshPiece* piece = nullptr;
};

// Recycles piece buffers between pipeline stages so steady state allocates nothing.
class PiecePool {
 public:
  MeshPiece* take() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (free_.empty()) {
      all_.push_back(std::make_unique<MeshPiece>());
      return all_.back().get();
    }
    MeshPiece* p = free_.back();
    free_.pop_back();
    return p;
  }
  void give(MeshPiece* p) {
    p->clear();
    // A rare huge piece should not pin its memory for the rest of the run.
    if (p->positions.capacity() > (size_t{16} << 20)) *p = MeshPiece();
    std::lock_guard<std::mutex> lock(mutex_);
    free_.push_back(p);
  }

 private:
  std::mutex mutex_;
  std::vector<std::unique_ptr<MeshPiece>> all_;
  std::vector<MeshPiece*> free_;
};

// One pass over all pieces into the writer, in order. Stops at the first error.
Status run_pass(uint64_t piece_count, const PieceFunction& piece, const PlyVertexLayout& layout,
                PlyWriter& writer, Progress* progress) {
  PiecePool pool;
  std::atomic<bool> failed{false};
  Status error;
  uint64_t next = 0;
  const size_t tokens = 4 * static_cast<size_t>(std::max(1, tbb::info::default_concurrency()));
  tbb::parallel_pipeline(
      tokens,
      tbb::make_filter<void, Token>(tbb::filter_mode::serial_in_order,
                                    [&](tbb::flow_control& fc) -> Token {
                                      if (next >= piece_count || failed.load()) {
                                        fc.stop();
                                        return {};
                                      }
                                      return Token{next++, pool.take()};
                                    }) &
          tbb::make_filter<Token, Token>(tbb::filter_mode::parallel,
                                         [&](Token t) {
                                           MeshBuilder builder(t.piece, layout);
                                           piece(t.index, builder);
                                           return t;
                                         }) &
          tbb::make_filter<Token, void>(tbb::filter_mode::serial_in_order, [&](Token t) {
            if (!failed.load()) {
              Status st = writer.add(*t.piece);
              if (!st) {
                error = st;
                failed.store(true);
              } else if (progress != nullptr) {
                progress->advance(t.piece->triangle_count());
              }
            }
            pool.give(t.piece);
          }));
  return error;
}

}  // namespace

Result<MeshCounts> write_pieces(uint64_t piece_count, const PieceFunction& piece,
                                const StreamOptions& options) {
  const MeshCounts counts = count_pieces(piece_count, piece, options.layout);
  auto writer = PlyWriter::create(options.path, options.layout, counts.vertices, counts.triangles,
                                  options.comments);
  if (!writer) return writer.status();
  Progress progress(options.label, "triangles", counts.triangles, options.quiet);
  Status st = run_pass(piece_count, piece, options.layout, **writer, &progress);
  if (st && (*writer)->needs_two_passes()) {
    // Non-seekable output: the vertex section went out first; now the faces, same pieces.
    st = (*writer)->begin_face_pass();
    Progress faces(options.label + " (faces)", "triangles", counts.triangles, options.quiet);
    if (st) st = run_pass(piece_count, piece, options.layout, **writer, &faces);
    if (st) faces.finish();
  }
  if (st) st = (*writer)->finish();
  if (!st) return st;
  progress.finish();
  return counts;
}

}  // namespace frontier::gen
