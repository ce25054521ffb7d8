// Progress on stderr for long runs: done/total, rate and ETA, at most four updates a second
// (on a terminal the line is redrawn in place; otherwise a line every five seconds).
// Silent when quiet. Call advance() from one thread at a time.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string_view>
#include <string>

namespace frontier {

class Progress {
 public:
  Progress(std::string label, std::string unit, uint64_t total, bool quiet);
  void advance(uint64_t n);
  // Prints the summary line (count, seconds, rate).
  void finish();
  double seconds() const;
  uint64_t done() const { return done_; }

 private:
  void print(bool final);

  std::string label_, unit_;
  uint64_t total_ = 0, done_ = 0;
  bool quiet_ = false, tty_ = false, printed_ = false;
  std::chrono::steady_clock::time_point start_, last_;
};

// "12.3M", "4.56G" style counts.
std::string human_count(double n);

// Parses a byte size for options: "1048576", "512K", "64M", "1.5G", "2T" (binary units, an
// optional trailing "B" or "iB"). nullopt for anything else, including 0-free garbage and overflow.
std::optional<uint64_t> parse_byte_size(std::string_view text);

}  // namespace frontier
