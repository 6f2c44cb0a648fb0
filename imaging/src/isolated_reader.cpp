#include "isolated_reader.h"

#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <exception>
#include <fstream>
#include <new>

#include "msk/core/error.h"

// AddressSanitizer reserves terabytes of address space for its shadow memory, so under it the child's memory is bounded
// by watching its resident size (residentBytes) instead of RLIMIT_AS.
#if defined(__SANITIZE_ADDRESS__)
#define MSK_ISOLATED_READER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MSK_ISOLATED_READER_ASAN 1
#endif
#endif

namespace msk::detail {

namespace {

// The child's answer: one status byte, then what the reader returned or the message.
enum class Answer : char { Result = 'M', IoProblem = 'I', OutOfMemory = 'O', Other = 'E' };

std::string encode(const TriangleMesh& m, MeshSpace space) {
  ByteWriter out;
  out.value<int64_t>(m.vertexCount());
  out.value<int64_t>(m.faceCount());
  out.value<int64_t>(static_cast<int64_t>(m.pointData.size()));
  out.value<int32_t>(space == MeshSpace::LPS ? 0 : 1);
  for (int v = 0; v < m.vertexCount(); ++v)
    for (int c = 0; c < 3; ++c) out.value<double>(m.vertices(v, c));
  for (int f = 0; f < m.faceCount(); ++f)
    for (int c = 0; c < 3; ++c) out.value<int32_t>(m.faces(f, c));
  for (const auto& [name, values] : m.pointData) {
    out.value<int64_t>(static_cast<int64_t>(name.size()));
    out.text(name);
    for (Eigen::Index i = 0; i < values.size(); ++i) out.value<double>(values[i]);
  }
  return std::move(out.bytes());
}

TriangleMesh decode(const std::string& bytes, const std::string& path, MeshSpace& space) {
  ByteReader d(bytes, path);
  const int64_t nv = d.value<int64_t>(), nf = d.value<int64_t>(), na = d.value<int64_t>();
  const int32_t s = d.value<int32_t>();
  if (nv < 0 || nf < 0 || na < 0 || static_cast<uint64_t>(nv) > bytes.size() / 24 ||
      static_cast<uint64_t>(nf) > bytes.size() / 12 || nv > INT32_MAX || nf > INT32_MAX)
    d.malformed();
  TriangleMesh m;
  m.vertices.resize(nv, 3);
  m.faces.resize(nf, 3);
  for (int64_t v = 0; v < nv; ++v)
    for (int c = 0; c < 3; ++c) m.vertices(v, c) = d.value<double>();
  for (int64_t f = 0; f < nf; ++f)
    for (int c = 0; c < 3; ++c) m.faces(f, c) = d.value<int32_t>();
  for (int64_t a = 0; a < na; ++a) {
    const int64_t len = d.value<int64_t>();
    if (len < 0 || static_cast<uint64_t>(len) > bytes.size()) d.malformed();
    const std::string name = d.text(static_cast<size_t>(len));
    Eigen::VectorXd values(nv);
    for (int64_t i = 0; i < nv; ++i) values[i] = d.value<double>();
    m.pointData[name] = values;
  }
  space = s == 0 ? MeshSpace::LPS : MeshSpace::RAS;
  return m;
}

/// Writes all of `bytes` to `fd` (the child's end of the pipe).
void writeAll(int fd, const std::string& bytes) {
  size_t at = 0;
  while (at < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + at, bytes.size() - at);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    at += static_cast<size_t>(n);
  }
}

[[noreturn]] void runChild(int fd, const std::function<std::string()>& read) {
  // A crash ends the child by its signal, whatever handlers the parent installed (a sanitizer's or a fuzzer's would
  // report the reader's crash as the parent's own).
  for (const int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGTRAP}) std::signal(sig, SIG_DFL);
  const rlimit cpu{static_cast<rlim_t>(kIsolatedReaderSeconds), static_cast<rlim_t>(kIsolatedReaderSeconds)};
  setrlimit(RLIMIT_CPU, &cpu);
#ifndef MSK_ISOLATED_READER_ASAN
  const rlimit memory{static_cast<rlim_t>(kIsolatedReaderBytes), static_cast<rlim_t>(kIsolatedReaderBytes)};
  setrlimit(RLIMIT_AS, &memory);
#endif
  std::string answer;
  try {
    answer = std::string(1, static_cast<char>(Answer::Result)) + read();
  } catch (const IoError& e) {
    answer = std::string(1, static_cast<char>(Answer::IoProblem)) + e.problem();
  } catch (const std::bad_alloc&) {
    answer = std::string(1, static_cast<char>(Answer::OutOfMemory));
  } catch (const std::exception& e) {
    answer = std::string(1, static_cast<char>(Answer::Other)) + e.what();
  }
  writeAll(fd, answer);
  ::close(fd);
  _exit(0);
}

/// Resident memory of process `pid`, bytes (0 if unknown).
long long residentBytes(pid_t pid) {
  std::ifstream statm("/proc/" + std::to_string(pid) + "/statm");
  long long size = 0, resident = 0;
  if (!(statm >> size >> resident)) return 0;
  return resident * ::sysconf(_SC_PAGESIZE);
}

}  // namespace

std::string ByteReader::text(size_t n) {
  if (n > left()) malformed();
  std::string s(n, '\0');
  take(s.data(), n);
  return s;
}

void ByteReader::take(void* p, size_t n) {
  if (n > left()) throw IoError(path_, "the reader's answer was cut short");
  std::memcpy(p, b_.data() + at_, n);
  at_ += n;
}

void ByteReader::malformed() const { throw IoError(path_, "the reader's answer is malformed"); }

std::string runInChildProcess(const std::string& path, const char* what, const std::function<std::string()>& read) {
  int fds[2];
  if (::pipe(fds) != 0)
    throw IoError(path, std::string("cannot start the ") + what + " reader: " + std::strerror(errno));
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw IoError(path, std::string("cannot start the ") + what + " reader: " + std::strerror(errno));
  }
  if (pid == 0) {
    ::close(fds[0]);
    runChild(fds[1], read);
  }
  ::close(fds[1]);
  // Waits for the answer at most twice the CPU limit in wall time (a child blocked, not computing, is not stopped by
  // that limit), then ends the child; ends it too if its resident memory passes kIsolatedReaderBytes.
  std::string bytes;
  char buffer[1 << 16];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2 * kIsolatedReaderSeconds);
  bool late = false, tooBig = false;
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    pollfd p{fds[0], POLLIN, 0};
    const int ready = left.count() > 0 ? ::poll(&p, 1, static_cast<int>(std::min<long long>(left.count(), 100))) : 0;
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0 && left.count() > 0) {
      if (residentBytes(pid) <= kIsolatedReaderBytes) continue;
      tooBig = true;
      ::kill(pid, SIGKILL);
      break;
    }
    if (ready <= 0) {
      late = true;
      ::kill(pid, SIGKILL);
      break;
    }
    const ssize_t n = ::read(fds[0], buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    bytes.append(buffer, static_cast<size_t>(n));
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  const std::string reader = std::string("the ") + what + " reader";
  const IoError outOfMemory(path, reader + " needed more than " + std::to_string(kIsolatedReaderBytes >> 30) +
                                      " GB for the file (malformed?)");
  if (tooBig) throw outOfMemory;
  if (late)
    throw IoError(
        path, reader + " gave no answer within " + std::to_string(2 * kIsolatedReaderSeconds) + " s (malformed file?)");
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    if (sig == SIGXCPU || sig == SIGKILL)
      throw IoError(path, reader + " ran for more than " + std::to_string(kIsolatedReaderSeconds) +
                              " s on the file (malformed?)");
    throw IoError(path, reader + " crashed on the file (" + strsignal(sig) + "): the file is malformed");
  }
  if (bytes.empty()) throw IoError(path, reader + " ended without an answer (the file is malformed)");
  switch (static_cast<Answer>(bytes[0])) {
    case Answer::Result:
      return bytes.substr(1);
    case Answer::IoProblem:
      throw IoError(path, bytes.substr(1));
    case Answer::OutOfMemory:
      throw outOfMemory;
    case Answer::Other:
      throw IoError(path, "cannot read the file: " + bytes.substr(1));
  }
  throw IoError(path, reader + " gave an unknown answer");
}

TriangleMesh readInChildProcess(const std::string& path, MeshSpace& space, const char* what,
                                const std::function<TriangleMesh(const std::string&, MeshSpace&)>& read) {
  const std::string bytes = runInChildProcess(path, what, [&] {
    MeshSpace found = space;
    const TriangleMesh m = read(path, found);
    return encode(m, found);
  });
  return decode(bytes, path, space);
}

}  // namespace msk::detail
