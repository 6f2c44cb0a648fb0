#pragma once
/// Typed exceptions of mskseg and the MSK_ASSERT invariant macro.
#include <stdexcept>
#include <string>

namespace msk {

/// Base of every error mskseg throws on purpose.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bad input or output file: what() reads "<file>: <problem>".
class IoError : public Error {
 public:
  IoError(std::string file, std::string problem)
      : Error(file + ": " + problem), file_(std::move(file)), problem_(std::move(problem)) {}
  /// The file concerned.
  const std::string& file() const { return file_; }
  /// The problem, without the file name.
  const std::string& problem() const { return problem_; }

 private:
  std::string file_, problem_;
};

/// A parameter outside its valid range: what() reads "<name> = <value>: <problem>".
class ParameterError : public Error {
 public:
  ParameterError(const std::string& name, const std::string& value, const std::string& problem)
      : Error(name + " = " + value + ": " + problem) {}
};

/// Throws ParameterError naming `name` unless 0 ≤ v ≤ 1 (stiffness γ, weights λ, friction μ, damping); NaN fails.
inline void checkUnitInterval(const std::string& name, double v) {
  if (!(v >= 0.0 && v <= 1.0)) throw ParameterError(name, std::to_string(v), "must be in [0, 1]");
}

/// A broken internal invariant (a bug): carries file and line.
class InternalError : public Error {
 public:
  using Error::Error;
};

/// Throws InternalError with file, line and message when cond is false.
#define MSK_ASSERT(cond, msg)                                                             \
  do {                                                                                    \
    if (!(cond))                                                                          \
      throw ::msk::InternalError(std::string(__FILE__) + ":" + std::to_string(__LINE__) + \
                                 ": assertion '" #cond "' failed: " + std::string(msg));  \
  } while (0)

}  // namespace msk
