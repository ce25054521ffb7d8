// TextTokenizer: the streaming front end of the text model readers (NFF, OBJ, OFF, ASCII PLY
// and the PLY header). It reads the file in 1 MiB chunks and hands out whitespace-separated
// tokens as views into its buffer, counting lines so that every error can name one.
//
// Invariants: a returned token view stays valid until the next call on the tokenizer; memory
// use is one chunk plus the longest token (tokens longer than kMaxToken are an error, so
// garbage without whitespace cannot grow the buffer). Blanks are space, tab, CR, FF and VT, so
// CRLF files read like LF files. Numbers are parsed with std::from_chars (locale independent).
#pragma once

#include "src/core/geometry.h"
#include "src/core/status.h"

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

namespace frontier {

class TextTokenizer {
 public:
  static constexpr size_t kChunk = size_t{1} << 20;
  static constexpr size_t kMaxToken = 4096;

  struct Options {
    bool hash_comments = true;       // a token starting with '#' comments out the rest of its line
    bool line_continuation = false;  // a backslash right before a line end joins the lines (OBJ)
  };

  TextTokenizer() = default;
  ~TextTokenizer();
  TextTokenizer(const TextTokenizer&) = delete;
  TextTokenizer& operator=(const TextTokenizer&) = delete;

  // Opens `path` for reading. Errors: NotFound / IoError naming the path.
  Status open(const std::string& path, Options options);

  // The next token, crossing line ends. Returns false at the end of the file or on a read error
  // (then status() is not ok).
  bool next(std::string_view& token);
  // The next token on the current line; false at the line end (which is not consumed) or at the
  // end of the file.
  bool next_on_line(std::string_view& token);
  // The next token as a statement keyword (NFF, OBJ): ok with `end` false and the keyword; ok
  // with `end` true at the end of the file; or the read error.
  Status next_statement(std::string_view& keyword, bool& end);
  // The token next() would return, without consuming it.
  bool peek(std::string_view& token);
  // Discards the rest of the current line, including its line end.
  void skip_line();
  // True when nothing but blanks (and a comment) remains on the current line.
  bool at_line_end();
  // Skips blanks, line ends and comments; returns the offset of the next byte, size() when the
  // file holds nothing else. Reads no token, so a long run of other bytes (zeros) costs one chunk.
  uint64_t skip_space();
  // Up to n (at most kMaxToken) bytes at the cursor, not consumed: fewer at the end of the file.
  std::string_view peek_bytes(size_t n);

  // Typed reads. Errors name the line: a missing token, a token that is not a number, or a
  // NaN/Inf value ("line 7: coordinate is not finite"). `what` names the expected value.
  Status next_double(double& out, std::string_view what);
  Status next_double_on_line(double& out, std::string_view what);
  Status next_vec3(Vec3& out, std::string_view what);  // three numbers, crossing lines
  Status next_vec3_on_line(Vec3& out, std::string_view what);
  Status next_int(int64_t& out, std::string_view what);
  Status next_int_on_line(int64_t& out, std::string_view what);

  // "path: line N: message" (Corruption), N the line of the last token returned.
  Status error(std::string_view message) const;
  // The read error if there was one, else "unexpected end of file (expected ...)" naming the
  // line of the last token.
  Status end_error(std::string_view expected) const;
  // Read error or over-long token; ok otherwise.
  const Status& status() const { return status_; }

  int64_t line() const { return token_line_; }
  const std::string& path() const { return path_; }
  int fd() const { return fd_; }
  uint64_t offset() const { return buffer_offset_ + pos_; }  // next unread byte
  uint64_t size() const { return file_size_; }

 private:
  enum class Stop { Token, LineEnd, FileEnd };
  Stop skip_blanks(bool cross_lines);
  size_t scan_token();  // length of the token at pos_ (may refill); 0 on error
  // Reads the token at the cursor (crossing line ends or not); consumes it unless peeking.
  bool take(std::string_view& token, bool cross_lines, bool consume);
  size_t ensure(size_t want);
  Status number_error(std::string_view token, std::string_view what, bool not_finite) const;
  // next_on_line, or the error of a line that ends before `what`.
  Status token_on_line(std::string_view& token, std::string_view what);

  std::string path_;
  Options options_;
  int fd_ = -1;
  uint64_t file_size_ = 0;
  std::unique_ptr<char[]> buffer_;
  size_t capacity_ = 0;
  size_t pos_ = 0;
  size_t end_ = 0;
  uint64_t buffer_offset_ = 0;  // file offset of buffer_[0]
  bool eof_ = false;
  int64_t line_ = 1;        // line of pos_
  int64_t token_line_ = 1;  // line of the last token returned
  Status status_;
};

// Parses a whole token as a number ("+1.5", "-2e3", "7"). Returns false when the token is not
// entirely a number; `finite` reports NaN/Inf (and overflow) for doubles.
bool parse_double(std::string_view token, double& out, bool& finite);
bool parse_int(std::string_view token, int64_t& out);

// A token quoted for an error message: at most 32 characters, non-printable bytes escaped.
std::string quote_token(std::string_view token);

}  // namespace frontier
