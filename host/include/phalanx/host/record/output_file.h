#pragma once
/// Files the record tools write (CSV exports, HTML reports): never over one of their own inputs, and never half
/// written over an existing file. The output is written to a temporary file in the same directory and renamed
/// into place only once it is complete and synced; a failure leaves the old file (if any) untouched.
#include <sys/types.h>

#include <string>

namespace phalanx::host::record {

/// The identity of a file as the kernel sees it (device + inode, after following symlinks).
struct FileId {
  dev_t dev = 0;
  ino_t ino = 0;
  bool valid = false;
  bool operator==(const FileId& o) const { return valid && o.valid && dev == o.dev && ino == o.ino; }
};
FileId fileId(const std::string& path);

/// "" or "refusing to write <output>: it is the input <input> (same file)" when output already names the file
/// input names (the same path, a symlink to it, or a hard link of it).
std::string refuseSameFile(const std::string& input, const std::string& output);

class AtomicOutputFile {
 public:
  AtomicOutputFile() = default;
  ~AtomicOutputFile();  ///< removes the temporary file unless commit() succeeded
  AtomicOutputFile(const AtomicOutputFile&) = delete;
  AtomicOutputFile& operator=(const AtomicOutputFile&) = delete;

  /// Create <dir of path>/.<name>.XXXXXX, mode `mode`. "" or an error naming path.
  std::string open(const std::string& path, mode_t mode = 0640);
  /// Appends bytes (buffered). false once anything failed.
  bool write(const void* data, std::size_t n);
  bool write(const std::string& s) { return write(s.data(), s.size()); }
  /// Flush, fsync, close, rename over path. "" or an error (the temporary file is then removed).
  std::string commit();
  const std::string& path() const { return path_; }

 private:
  bool flushBuffer();
  std::string path_, temp_;
  int fd_ = -1;
  int err_no_ = 0;
  std::string buffer_;
};

}  // namespace phalanx::host::record
