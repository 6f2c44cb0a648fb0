#include "msk/segmentation/mesh_cache.h"

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/imaging/checksum.h"

#if defined(__linux__)
#include <elf.h>
#include <link.h>
#endif

namespace msk {

namespace {

constexpr char kMagic[8] = {'M', 'S', 'K', 'M', 'E', 'S', 'H', '1'};

#if defined(__linux__)
/// dl_iterate_phdr() callback: the build ID note of the first object listed (the program itself) into *data.
int readBuildId(dl_phdr_info* info, size_t, void* data) {
  auto* out = static_cast<std::string*>(data);
  for (int h = 0; h < info->dlpi_phnum; ++h) {
    const ElfW(Phdr)& ph = info->dlpi_phdr[h];
    if (ph.p_type != PT_NOTE) continue;
    const char* p = reinterpret_cast<const char*>(info->dlpi_addr + ph.p_vaddr);
    const char* end = p + ph.p_memsz;
    while (p + sizeof(ElfW(Nhdr)) <= end) {
      ElfW(Nhdr) note;
      std::memcpy(&note, p, sizeof note);
      const char* name = p + sizeof note;
      const char* desc = name + ((note.n_namesz + 3) & ~3u);
      if (note.n_type == NT_GNU_BUILD_ID && note.n_namesz == 4 && std::memcmp(name, "GNU", 4) == 0 &&
          desc + note.n_descsz <= end) {
        static const char* hex = "0123456789abcdef";
        for (unsigned i = 0; i < note.n_descsz; ++i) {
          const auto b = static_cast<unsigned char>(desc[i]);
          *out += hex[b >> 4];
          *out += hex[b & 15];
        }
        return 1;
      }
      p = desc + ((note.n_descsz + 3) & ~3u);
    }
  }
  return 1;  // only the program itself
}
#endif

/// The build ID, or else a SHA-256 of the program's file, or else "" (computed once).
const std::string& programIdentity() {
  static const std::string id = [] {
    std::string s = programBuildId();
    if (s.empty()) {
      try {
        s = sha256File("/proc/self/exe");
      } catch (const Error&) {
      }
    }
    return s;
  }();
  return id;
}

template <typename T>
void put(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}

/// The mesh's vertex and face counts and its raw values (the bytes an entry stores and a key hashes).
std::string meshBytes(const TriangleMesh& m) {
  std::string out;
  put(out, static_cast<int64_t>(m.vertexCount()));
  put(out, static_cast<int64_t>(m.faceCount()));
  for (int v = 0; v < m.vertexCount(); ++v)
    for (int a = 0; a < 3; ++a) put(out, static_cast<double>(m.vertices(v, a)));
  for (int f = 0; f < m.faceCount(); ++f)
    for (int a = 0; a < 3; ++a) put(out, static_cast<int32_t>(m.faces(f, a)));
  return out;
}

/// The mesh meshBytes() wrote, or false if `bytes` are not one.
bool meshFromBytes(const std::string& bytes, TriangleMesh& m) {
  int64_t nv = 0, nf = 0;
  if (bytes.size() < 2 * sizeof(int64_t)) return false;
  std::memcpy(&nv, bytes.data(), sizeof nv);
  std::memcpy(&nf, bytes.data() + sizeof nv, sizeof nf);
  if (nv < 0 || nf < 0 || nv > (int64_t{1} << 31) || nf > (int64_t{1} << 31) ||
      bytes.size() != 2 * sizeof(int64_t) + static_cast<size_t>(nv) * 3 * sizeof(double) +
                          static_cast<size_t>(nf) * 3 * sizeof(int32_t))
    return false;
  m.vertices.resize(nv, 3);
  m.faces.resize(nf, 3);
  const char* p = bytes.data() + 2 * sizeof(int64_t);
  for (int64_t v = 0; v < nv; ++v)
    for (int a = 0; a < 3; ++a, p += sizeof(double)) std::memcpy(&m.vertices(v, a), p, sizeof(double));
  for (int64_t f = 0; f < nf; ++f)
    for (int a = 0; a < 3; ++a, p += sizeof(int32_t)) {
      int32_t i;
      std::memcpy(&i, p, sizeof i);
      if (i < 0 || i >= nv) return false;
      m.faces(f, a) = i;
    }
  return true;
}

std::string readWhole(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

std::string programBuildId() {
  std::string id;
#if defined(__linux__)
  dl_iterate_phdr(readBuildId, &id);
#endif
  return id;
}

MeshCache::MeshCache(std::string dir) : dir_(std::move(dir)) {
  if (dir_.empty()) throw ParameterError("--template-cache", "\"\"", "must name a folder");
}

TriangleMesh MeshCache::get(const std::string& op, const TriangleMesh& input,
                            const std::function<TriangleMesh()>& derive) {
  const std::string identity = programIdentity();
  if (identity.empty()) {  // nothing tells this program's entries from another's: derive every time
    ++misses_;
    return derive();
  }
  const std::string key = sha256Text(op + '\x1f' + identity + '\x1f' + meshBytes(input));
  const std::string path = dir_ + "/" + key + ".mesh";
  // An entry: the magic, the key, the mesh's bytes, and the SHA-256 of those bytes.
  const std::string entry = readWhole(path);
  if (!entry.empty()) {
    const size_t head = sizeof kMagic + key.size(), tail = 64;
    TriangleMesh m;
    if (entry.size() > head + tail && std::memcmp(entry.data(), kMagic, sizeof kMagic) == 0 &&
        entry.compare(sizeof kMagic, key.size(), key) == 0) {
      const std::string body = entry.substr(head, entry.size() - head - tail);
      if (entry.compare(entry.size() - tail, tail, sha256Text(body)) == 0 && meshFromBytes(body, m)) {
        ++hits_;
        return m;
      }
    }
    log::warn(path + ": a damaged template cache entry; deriving it again");
  }
  TriangleMesh derived = derive();
  ++misses_;
  try {
    std::filesystem::create_directories(dir_);
    const std::string body = meshBytes(derived);
    writeAtomically(path, [&](const std::string& tmp) {
      std::ofstream out(tmp, std::ios::binary);
      out.write(kMagic, sizeof kMagic);
      out << key << body << sha256Text(body);
      out.close();
      if (!out) throw IoError(tmp, "cannot write the template cache entry");
    });
  } catch (const std::exception& e) {
    log::warn(std::string("template cache not written: ") + e.what());
  }
  return derived;
}

}  // namespace msk
