#pragma once
// Reading a file in a child process: a reader that crashes, exhausts memory or runs unbounded on a malformed file
// (VTK's XML reader does all three) ends the child, and the caller gets one IoError naming the file.
#include <functional>
#include <string>

#include "msk/core/triangle_mesh.h"
#include "msk/imaging/mesh_io.h"

namespace msk::detail {

/// Address space (bytes) and CPU time (s) the child may use.
constexpr long long kIsolatedReaderBytes = 3LL << 30;
constexpr int kIsolatedReaderSeconds = 60;

/// Bytes written and read in order (the child's answer).
class ByteWriter {
 public:
  template <typename T>
  void value(T v) {
    bytes_.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void text(const std::string& s) { bytes_ += s; }
  std::string& bytes() { return bytes_; }

 private:
  std::string bytes_;
};

/// Reads what a ByteWriter wrote; throws IoError(path, ...) if the bytes run out.
class ByteReader {
 public:
  ByteReader(const std::string& bytes, const std::string& path) : b_(bytes), path_(path) {}
  template <typename T>
  T value() {
    T v;
    take(&v, sizeof v);
    return v;
  }
  std::string text(size_t n);
  /// Bytes not yet read.
  size_t left() const { return b_.size() - at_; }
  /// Throws IoError(path, "the reader's answer is malformed").
  [[noreturn]] void malformed() const;

 private:
  void take(void* p, size_t n);
  const std::string& b_;
  const std::string& path_;
  size_t at_ = 0;
};

/// Runs `read()` in a forked child limited to kIsolatedReaderBytes and kIsolatedReaderSeconds and returns the bytes
/// it returned. The reader's own IoError comes back as it was (with `path`); a crash, a signal, running out of memory
/// or time become IoError(path, "<what> reader ..."). Call it while the process runs no other threads (fork() copies
/// only the calling one).
std::string runInChildProcess(const std::string& path, const char* what, const std::function<std::string()>& read);

/// Runs `read(path, space)` in a forked child limited to kIsolatedReaderBytes and kIsolatedReaderSeconds and returns
/// its mesh and space. The reader's own IoError comes back as it was; a crash, a signal, running out of memory or time
/// become IoError(path, "<what> reader ..."). Call it while the process runs no other threads (fork() copies only the
/// calling one).
TriangleMesh readInChildProcess(const std::string& path, MeshSpace& space, const char* what,
                                const std::function<TriangleMesh(const std::string&, MeshSpace&)>& read);

}  // namespace msk::detail
