#pragma once
// Errors that reach a user (bad files, bad parameters, missing devices) are exceptions carrying
// *what* was wrong and *where* (a file path or a parameter name). They are caught only at the
// CLI boundary, which prints one line and exits non-zero (DESIGN.md §3). Programming errors are
// asserts, not exceptions.
#include <stdexcept>
#include <string>

namespace odvr {

class Error : public std::runtime_error {
 public:
  // `where` names the file, device or parameter; `reason` says what is wrong with it.
  Error(std::string where, std::string reason)
      : std::runtime_error(where.empty() ? reason : where + ": " + reason),
        where_(std::move(where)),
        reason_(std::move(reason)) {}

  const std::string& where() const { return where_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string where_;
  std::string reason_;
};

// A bad command-line value: the CLI maps it to exit code 2, like CLI11's own errors.
class UsageError : public Error {
 public:
  using Error::Error;
};

}  // namespace odvr
