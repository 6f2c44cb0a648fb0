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

/// Runs `read(path, space)` in a forked child limited to kIsolatedReaderBytes and kIsolatedReaderSeconds and returns
/// its mesh and space. The reader's own IoError comes back as it was; a crash, a signal, running out of memory or time
/// become IoError(path, "<what> reader ..."). Call it while the process runs no other threads (fork() copies only the
/// calling one).
TriangleMesh readInChildProcess(const std::string& path, MeshSpace& space, const char* what,
                                const std::function<TriangleMesh(const std::string&, MeshSpace&)>& read);

}  // namespace msk::detail
