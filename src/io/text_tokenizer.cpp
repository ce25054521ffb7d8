// TextTokenizer: chunked reads, blank skipping with line counting, whole-token number parsing.
#include "src/io/text_tokenizer.h"

#include <fmt/format.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace frontier {
namespace {

// Blanks separate tokens without ending a line.
inline bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

}  // namespace

TextTokenizer::~TextTokenizer() {
  if (fd_ >= 0) ::close(fd_);
}

Status TextTokenizer::open(const std::string& path, Options options) {
  path_ = path;
  options_ = options;
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) {
    const int err = errno;
    std::string msg = fmt::format("{}: cannot open: {}", path, std::strerror(err));
    return err == ENOENT ? Status::not_found(std::move(msg)) : Status::io_error(std::move(msg));
  }
  struct stat st {};
  if (::fstat(fd_, &st) != 0) return Status::io_error(fmt::format("{}: cannot stat: {}", path, std::strerror(errno)));
  if (S_ISDIR(st.st_mode)) return Status::io_error(fmt::format("{}: is a directory", path));
  file_size_ = st.st_size > 0 ? static_cast<uint64_t>(st.st_size) : 0;
  // Small files get a small buffer; kMaxToken of slack lets a token straddle a chunk boundary.
  capacity_ = static_cast<size_t>(std::min<uint64_t>(kChunk, file_size_ + 1)) + kMaxToken;
  buffer_ = std::make_unique<char[]>(capacity_);
  return Status::ok();
}

size_t TextTokenizer::ensure(size_t want) {
  size_t have = end_ - pos_;
  if (have >= want || eof_) return have;
  std::memmove(buffer_.get(), buffer_.get() + pos_, have);
  buffer_offset_ += pos_;
  pos_ = 0;
  end_ = have;
  while (end_ < want && !eof_) {
    const ssize_t r = ::read(fd_, buffer_.get() + end_, capacity_ - end_);
    if (r < 0) {
      if (errno == EINTR) continue;
      status_ = Status::io_error(fmt::format("{}: byte {}: read failed: {}", path_,
                                             buffer_offset_ + end_, std::strerror(errno)));
      eof_ = true;
    } else if (r == 0) {
      eof_ = true;
    } else {
      end_ += static_cast<size_t>(r);
    }
  }
  return end_ - pos_;
}

TextTokenizer::Stop TextTokenizer::skip_blanks(bool cross_lines) {
  for (;;) {
    if (pos_ == end_ && ensure(1) == 0) return Stop::FileEnd;
    const char c = buffer_[pos_];
    if (c == '\n') {
      if (!cross_lines) return Stop::LineEnd;
      ++line_;
      ++pos_;
    } else if (is_blank(c)) {
      ++pos_;
    } else if (c == '\\' && options_.line_continuation) {
      const size_t have = ensure(3);
      if (have >= 2 && buffer_[pos_ + 1] == '\n') {
        pos_ += 2;
        ++line_;
      } else if (have >= 3 && buffer_[pos_ + 1] == '\r' && buffer_[pos_ + 2] == '\n') {
        pos_ += 3;
        ++line_;
      } else {
        return Stop::Token;
      }
    } else if (c == '#' && options_.hash_comments) {
      // Skip to the line end but leave it, so next_on_line() sees the end of the line.
      for (;;) {
        const char* nl = static_cast<const char*>(std::memchr(buffer_.get() + pos_, '\n', end_ - pos_));
        if (nl != nullptr) {
          pos_ = static_cast<size_t>(nl - buffer_.get());
          break;
        }
        pos_ = end_;
        if (ensure(1) == 0) return Stop::FileEnd;
      }
    } else {
      return Stop::Token;
    }
  }
}

size_t TextTokenizer::scan_token() {
  // pos_ is at a non-blank character; the token is at least that character long.
  size_t len = 1;
  for (;;) {
    const char* b = buffer_.get() + pos_;
    const size_t have = end_ - pos_;
    while (len < have) {
      const char c = b[len];
      if (c == '\n' || is_blank(c) || (c == '\\' && options_.line_continuation)) return len;
      ++len;
    }
    if (eof_) return len;
    if (len >= kMaxToken) {
      status_ = Status::corruption(
          fmt::format("{}: line {}: token longer than {} bytes", path_, line_, kMaxToken));
      eof_ = true;
      return 0;
    }
    if (ensure(len + 1) <= len) return status_.is_ok() ? len : 0;
  }
}

bool TextTokenizer::take(std::string_view& token, bool cross_lines, bool consume) {
  if (skip_blanks(cross_lines) != Stop::Token) return false;
  const size_t len = scan_token();
  if (len == 0) return false;
  token = std::string_view(buffer_.get() + pos_, len);
  if (consume) {
    token_line_ = line_;
    pos_ += len;
  }
  return true;
}

bool TextTokenizer::next(std::string_view& token) { return take(token, true, true); }
bool TextTokenizer::next_on_line(std::string_view& token) { return take(token, false, true); }
bool TextTokenizer::peek(std::string_view& token) { return take(token, true, false); }

Status TextTokenizer::next_statement(std::string_view& keyword, bool& end) {
  end = false;
  if (next(keyword)) return Status::ok();
  if (!status_.is_ok()) return status_;
  end = true;
  return Status::ok();
}

void TextTokenizer::skip_line() {
  for (;;) {
    if (pos_ == end_ && ensure(1) == 0) return;
    const char* nl = static_cast<const char*>(std::memchr(buffer_.get() + pos_, '\n', end_ - pos_));
    if (nl != nullptr) {
      pos_ = static_cast<size_t>(nl - buffer_.get()) + 1;
      ++line_;
      return;
    }
    pos_ = end_;
  }
}

bool TextTokenizer::at_line_end() { return skip_blanks(false) != Stop::Token; }

uint64_t TextTokenizer::skip_space() {
  skip_blanks(true);
  return offset();
}

std::string_view TextTokenizer::peek_bytes(size_t n) {
  const size_t have = ensure(std::min(n, kMaxToken));
  return {buffer_.get() + pos_, std::min(have, n)};
}

Status TextTokenizer::error(std::string_view message) const {
  return Status::corruption(fmt::format("{}: line {}: {}", path_, token_line_, message));
}

Status TextTokenizer::end_error(std::string_view expected) const {
  if (!status_.is_ok()) return status_;
  return Status::corruption(
      fmt::format("{}: line {}: unexpected end of file (expected {})", path_, token_line_, expected));
}

Status TextTokenizer::number_error(std::string_view token, std::string_view what,
                                   bool not_finite) const {
  if (not_finite) return error(fmt::format("{} is not finite", what));
  return error(fmt::format("expected a number ({}), got {}", what, quote_token(token)));
}

Status TextTokenizer::next_double(double& out, std::string_view what) {
  std::string_view t;
  if (!next(t)) return end_error(what);
  bool finite = true;
  if (!parse_double(t, out, finite) || !finite) return number_error(t, what, !finite);
  return Status::ok();
}

Status TextTokenizer::token_on_line(std::string_view& token, std::string_view what) {
  if (next_on_line(token)) return Status::ok();
  if (!status_.is_ok()) return status_;
  return error(fmt::format("line ends before {}", what));
}

Status TextTokenizer::next_double_on_line(double& out, std::string_view what) {
  std::string_view t;
  if (Status s = token_on_line(t, what); !s) return s;
  bool finite = true;
  if (!parse_double(t, out, finite) || !finite) return number_error(t, what, !finite);
  return Status::ok();
}

Status TextTokenizer::next_vec3(Vec3& out, std::string_view what) {
  for (int k = 0; k < 3; ++k) {
    Status s = next_double(out[k], what);
    if (!s) return s;
  }
  return Status::ok();
}

Status TextTokenizer::next_vec3_on_line(Vec3& out, std::string_view what) {
  for (int k = 0; k < 3; ++k) {
    Status s = next_double_on_line(out[k], what);
    if (!s) return s;
  }
  return Status::ok();
}

Status TextTokenizer::next_int(int64_t& out, std::string_view what) {
  std::string_view t;
  if (!next(t)) return end_error(what);
  if (!parse_int(t, out)) return error(fmt::format("expected an integer ({}), got {}", what, quote_token(t)));
  return Status::ok();
}

Status TextTokenizer::next_int_on_line(int64_t& out, std::string_view what) {
  std::string_view t;
  if (Status s = token_on_line(t, what); !s) return s;
  if (!parse_int(t, out)) return error(fmt::format("expected an integer ({}), got {}", what, quote_token(t)));
  return Status::ok();
}

bool parse_double(std::string_view token, double& out, bool& finite) {
  finite = true;
  const char* first = token.data();
  const char* last = first + token.size();
  if (first != last && *first == '+') {
    ++first;
    if (first != last && (*first == '+' || *first == '-')) return false;
  }
  if (first == last) return false;
  const auto [ptr, ec] = std::from_chars(first, last, out, std::chars_format::general);
  if (ptr != last) return false;
  if (ec == std::errc::result_out_of_range) {
    // Overflow is not finite; underflow rounds to a tiny value or zero, as strtod does.
    char copy[64];
    const size_t n = static_cast<size_t>(last - first);
    if (n >= sizeof(copy)) {
      finite = false;
      return true;
    }
    std::memcpy(copy, first, n);
    copy[n] = '\0';
    out = std::strtod(copy, nullptr);
  } else if (ec != std::errc()) {
    return false;
  }
  finite = std::isfinite(out);
  return true;
}

bool parse_int(std::string_view token, int64_t& out) {
  const char* first = token.data();
  const char* last = first + token.size();
  if (first != last && *first == '+') {
    ++first;
    if (first != last && *first == '-') return false;
  }
  if (first == last) return false;
  const auto [ptr, ec] = std::from_chars(first, last, out);
  return ec == std::errc() && ptr == last;
}

std::string quote_token(std::string_view token) {
  std::string s = "'";
  const size_t n = std::min<size_t>(token.size(), 32);
  for (size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    if (c >= 0x20 && c < 0x7f && c != '\'' && c != '\\') {
      s += static_cast<char>(c);
    } else {
      s += fmt::format("\\x{:02x}", c);
    }
  }
  if (token.size() > n) s += "...";
  s += "'";
  return s;
}

}  // namespace frontier
