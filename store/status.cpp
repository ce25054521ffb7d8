// Status formatting.
#include "store/status.h"

namespace frontier {

std::string Status::to_string() const {
  const char* name = "OK";
  switch (code_) {
    case Code::Ok: return "OK";
    case Code::InvalidArgument: name = "Invalid argument"; break;
    case Code::NotFound: name = "Not found"; break;
    case Code::Corruption: name = "Corruption"; break;
    case Code::IoError: name = "I/O error"; break;
    case Code::Unsupported: name = "Unsupported"; break;
  }
  return std::string(name) + ": " + message_;
}

}  // namespace frontier
