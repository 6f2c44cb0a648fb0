#pragma once
/// A folder of meshes derived from templates (remeshed, decimated), so that the cases of a cohort, each its own
/// process, derive them from one set of templates once instead of once per case.
///
/// An entry is keyed by the SHA-256 of the operation's name and parameters, of the input mesh's bytes and of the
/// running program's build ID (an entry made by another build of mskseg is never used). It holds the derived mesh and
/// a SHA-256 of its bytes; an entry that is unreadable, truncated, of another key or whose checksum does not match is
/// derived again and rewritten (with a warning). Entries are written atomically, so cases running at the same time
/// may share the folder.
#include <atomic>
#include <functional>
#include <string>

#include "msk/core/triangle_mesh.h"

namespace msk {

class MeshCache {
 public:
  /// The cache in folder `dir` (created when the first entry is written).
  explicit MeshCache(std::string dir);

  /// The mesh `derive()` makes of `input` by operation `op` (its name and every parameter that changes the result):
  /// from the folder when an intact entry is there, else derived and stored. The result is the same bytes either way.
  TriangleMesh get(const std::string& op, const TriangleMesh& input, const std::function<TriangleMesh()>& derive);

  /// Entries found and used.
  int hits() const { return hits_; }
  /// Entries derived (and stored).
  int misses() const { return misses_; }
  const std::string& folder() const { return dir_; }

 private:
  std::string dir_;
  std::atomic<int> hits_{0}, misses_{0};
};

/// The running program's build ID (the ELF note the linker writes, in hexadecimal); empty where there is none.
std::string programBuildId();

}  // namespace msk
