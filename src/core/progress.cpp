// Rate-limited progress line (see header).
#include "src/core/progress.h"

#include <fmt/format.h>

#include <cctype>
#include <cstdio>
#include <string>

#include <unistd.h>

namespace frontier {

std::string human_count(double n) {
  if (n >= 1e9) return fmt::format("{:.2f}G", n / 1e9);
  if (n >= 1e6) return fmt::format("{:.1f}M", n / 1e6);
  if (n >= 1e4) return fmt::format("{:.1f}k", n / 1e3);
  return fmt::format("{:.0f}", n);
}

std::optional<uint64_t> parse_byte_size(std::string_view text) {
  size_t i = 0;
  while (i < text.size() && (std::isdigit(static_cast<unsigned char>(text[i])) || text[i] == '.')) ++i;
  if (i == 0) return std::nullopt;
  double value = 0.0;
  try {
    size_t used = 0;
    value = std::stod(std::string(text.substr(0, i)), &used);
    if (used != i) return std::nullopt;
  } catch (const std::exception&) {
    return std::nullopt;
  }
  std::string unit(text.substr(i));
  for (char& c : unit) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (unit.size() >= 2 && unit.substr(unit.size() - 2) == "IB") unit.resize(unit.size() - 2);
  else if (!unit.empty() && unit.back() == 'B') unit.pop_back();
  double scale = 1.0;
  if (unit == "K") scale = 1024.0;
  else if (unit == "M") scale = 1024.0 * 1024.0;
  else if (unit == "G") scale = 1024.0 * 1024.0 * 1024.0;
  else if (unit == "T") scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
  else if (!unit.empty()) return std::nullopt;
  const double bytes = value * scale;
  if (!(bytes >= 0.0) || bytes >= 1.8e19) return std::nullopt;
  return static_cast<uint64_t>(bytes);
}

Progress::Progress(std::string label, std::string unit, uint64_t total, bool quiet)
    : label_(std::move(label)), unit_(std::move(unit)), total_(total), quiet_(quiet) {
  tty_ = ::isatty(STDERR_FILENO) != 0;
  start_ = last_ = std::chrono::steady_clock::now();
}

double Progress::seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::advance(uint64_t n) {
  done_ += n;
  if (quiet_) return;
  const auto now = std::chrono::steady_clock::now();
  const auto interval = tty_ ? std::chrono::milliseconds(250) : std::chrono::milliseconds(5000);
  if (now - last_ < interval) return;
  last_ = now;
  print(false);
}

void Progress::print(bool final) {
  const double secs = seconds();
  const double rate = secs > 0.0 ? static_cast<double>(done_) / secs : 0.0;
  std::string line;
  if (final) {
    line = fmt::format("{}: {} {} in {:.1f} s ({} {}/s)", label_, human_count(double(done_)),
                       unit_, secs, human_count(rate), unit_);
  } else {
    const double frac = total_ > 0 ? static_cast<double>(done_) / static_cast<double>(total_) : 0.0;
    const double eta = rate > 0.0 ? static_cast<double>(total_ - std::min(done_, total_)) / rate : 0.0;
    const int e = static_cast<int>(eta + 0.5);
    line = fmt::format("{}: {:3.0f}% {}/{} {}  {} {}/s  ETA {}:{:02}:{:02}", label_, 100.0 * frac,
                       human_count(double(done_)), human_count(double(total_)), unit_,
                       human_count(rate), unit_, e / 3600, (e / 60) % 60, e % 60);
  }
  if (tty_)
    std::fprintf(stderr, "\r%-79s%s", line.c_str(), final ? "\n" : "");
  else
    std::fprintf(stderr, "%s\n", line.c_str());
  std::fflush(stderr);
  printed_ = true;
}

void Progress::finish() {
  if (!quiet_) print(true);
}

}  // namespace frontier
