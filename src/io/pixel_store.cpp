#include "fillgs/io/pixel_store.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "fillgs/base/error.hpp"
#include "fillgs/base/limits.hpp"

namespace fillgs {

struct PixelStore::File {
  int fd = -1;
  std::string path;  ///< where it was made (already unlinked): for messages
  ~File() {
    if (fd >= 0) ::close(fd);
  }
};

void PixelStore::reset(const std::vector<size_t>& sizes, size_t budget, const std::string& spill_dir) {
  sizes_ = sizes;
  offsets_.assign(sizes.size(), 0);
  total_ = 0;
  for (size_t i = 0; i < sizes.size(); ++i) offsets_[i] = total_, total_ += sizes[i];
  memory_.clear();
  file_.reset();
  if (total_ <= budget) {
    memory_.resize(sizes.size());
    return;
  }
  // $TMPDIR as the user set it (std::filesystem::temp_directory_path throws a message that
  // does not say which variable named the missing folder).
  const char* tmpdir = std::getenv("TMPDIR");
  const bool from_env = spill_dir.empty() && tmpdir && *tmpdir;
  const std::string dir = !spill_dir.empty() ? spill_dir : from_env ? std::string(tmpdir) : std::string("/tmp");
  std::string templ = (std::filesystem::path(dir) / "fillgs-images-XXXXXX").string();
  auto f = std::make_shared<File>();
  f->fd = ::mkstemp(templ.data());
  if (f->fd < 0)
    throw_error(dir, from_env ? " (TMPDIR)" : "", ": cannot make the image cache for ", total_, " bytes of images (", std::strerror(errno),
                "); give another folder with TMPDIR or raise --image-memory");
  f->path = templ;
  ::unlink(templ.c_str());  // gone with the process, whatever ends it
  file_ = std::move(f);
}

void PixelStore::put(size_t i, std::vector<uint8_t>&& pixels) {
  if (i >= sizes_.size() || pixels.size() != sizes_[i]) throw_error("image store: image ", i, " has ", pixels.size(), " bytes, expected ", sizes_.at(i));
  if (!file_) {
    memory_[i] = std::move(pixels);
    return;
  }
  size_t done = 0;
  while (done < pixels.size()) {
    const ssize_t n = ::pwrite(file_->fd, pixels.data() + done, pixels.size() - done, off_t(offsets_[i] + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw_error(file_->path, ": cannot write the image cache (", n < 0 ? std::strerror(errno) : "no progress",
                  "); free disk space there, give another folder with TMPDIR or raise --image-memory");
    done += size_t(n);
  }
}

const std::vector<uint8_t>& PixelStore::get(size_t i, std::vector<uint8_t>& out) const {
  if (!file_) return memory_.at(i);
  out.resize(sizes_.at(i));
  size_t done = 0;
  while (done < out.size()) {
    const ssize_t n = ::pread(file_->fd, out.data() + done, out.size() - done, off_t(offsets_[i] + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw_error(file_->path, ": cannot read image ", i, " back from the image cache (", n < 0 ? std::strerror(errno) : "short file", ")");
    done += size_t(n);
  }
  return out;
}

std::vector<uint8_t> PixelStore::take(size_t i) {
  if (!file_) return std::move(memory_.at(i));
  std::vector<uint8_t> out;
  get(i, out);
  return out;
}

size_t default_image_budget() { return allocation_cap() / 4; }

}  // namespace fillgs
