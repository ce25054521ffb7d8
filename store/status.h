// Status and Result<T>: how frontier reports failures that come from outside the program
// (files, disks, user options, decoding). Programmer errors are assertions, not Statuses.
// A Status is cheap when ok (no allocation); its message names the file and the line, byte
// offset or page where the problem was found. It lives in store/, the lowest layer, and every
// layer above uses this one type. Unsupported: a well-formed input this reader cannot read
// (a newer format version, unknown flags).
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace frontier {

class Status {
 public:
  enum class Code { Ok, InvalidArgument, NotFound, Corruption, IoError, Unsupported };

  Status() = default;
  static Status ok() { return Status(); }
  static Status invalid_argument(std::string msg) { return {Code::InvalidArgument, std::move(msg)}; }
  static Status not_found(std::string msg) { return {Code::NotFound, std::move(msg)}; }
  static Status corruption(std::string msg) { return {Code::Corruption, std::move(msg)}; }
  static Status io_error(std::string msg) { return {Code::IoError, std::move(msg)}; }
  static Status unsupported(std::string msg) { return {Code::Unsupported, std::move(msg)}; }

  bool is_ok() const { return code_ == Code::Ok; }
  explicit operator bool() const { return is_ok(); }
  Code code() const { return code_; }
  const std::string& message() const { return message_; }
  // "Corruption: file.ply: line 12: ..." style text for the terminal.
  std::string to_string() const;
  // The same code with `prefix` (say "file: ") before the message: context added on the way up.
  Status prefixed(std::string_view prefix) const {
    return is_ok() ? *this : Status(code_, std::string(prefix) + message_);
  }

 private:
  Status(Code code, std::string msg) : code_(code), message_(std::move(msg)) {}
  Code code_ = Code::Ok;
  std::string message_;
};

// Either a value or a non-ok Status. REQUIRES: value() only when is_ok().
template <typename T>
class Result {
 public:
  Result(T value) : data_(std::move(value)) {}            // NOLINT(google-explicit-constructor)
  Result(Status status) : data_(std::move(status)) {}     // NOLINT(google-explicit-constructor)
  bool is_ok() const { return std::holds_alternative<T>(data_); }
  explicit operator bool() const { return is_ok(); }
  const Status& status() const {
    static const Status kOk;
    return is_ok() ? kOk : std::get<Status>(data_);
  }
  T& value() & { return std::get<T>(data_); }
  const T& value() const& { return std::get<T>(data_); }
  T&& value() && { return std::get<T>(std::move(data_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() { return value(); }

 private:
  std::variant<T, Status> data_;
};

}  // namespace frontier
