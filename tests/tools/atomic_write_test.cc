// The output rule of sfrt/io/atomic_write.h: regular files are replaced atomically, devices and
// FIFOs are written in place, symbolic links are followed and survive, failures are reported.
#include "sfrt/pipeline/io/atomic_write.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

namespace sfrt::io {
namespace {

namespace fs = std::filesystem;

std::span<const uint8_t> Bytes(const std::string& s) {
  return {reinterpret_cast<const uint8_t*>(s.data()), s.size()};
}

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class AtomicWriteTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(::testing::TempDir()) /
           (std::string("sfrt_atomic_") + info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A private node of the character device `major`,`minor` where this process may create one,
  // so a regression replaces only that node; otherwise `fallback` itself (/dev/..., whose
  // directory an unprivileged process cannot write, so cannot replace). Never the real device
  // as root.
  std::string PrivateDevice(const char* name, unsigned major, unsigned minor,
                            const std::string& fallback) const {
    const std::string node = (dir_ / name).string();
    if (::mknod(node.c_str(), S_IFCHR | 0666, ::makedev(major, minor)) == 0) {
      const int fd = ::open(node.c_str(), O_WRONLY);  // fails on a nodev mount
      if (fd >= 0) {
        ::close(fd);
        return node;
      }
      ::unlink(node.c_str());
    }
    return fallback;
  }
  // Fails every write with ENOSPC, like /dev/full (1,7).
  std::string FullDevice() const { return PrivateDevice("full", 1, 7, "/dev/full"); }
  // Discards every write, like /dev/null (1,3).
  std::string NullDevice() const { return PrivateDevice("null", 1, 3, "/dev/null"); }

  static bool IsCharDevice(const std::string& p) {
    struct stat st;
    return ::lstat(p.c_str(), &st) == 0 && S_ISCHR(st.st_mode);
  }

  fs::path dir_;
};

TEST_F(AtomicWriteTest, AtomicWriteReplacesARegularFile) {
  const fs::path p = dir_ / "out.bin";
  std::ofstream(p) << "old";
  ASSERT_TRUE(WriteFileAtomically(p.string(), Bytes("new contents")).ok());
  EXPECT_EQ(Slurp(p), "new contents");
  EXPECT_TRUE(fs::is_regular_file(fs::symlink_status(p)));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST_F(AtomicWriteTest, ANewFileGetsTheUsualPermissionsUnderTheUmask) {
  const mode_t old = ::umask(027);
  const fs::path p = dir_ / "new.bin";
  const Status s = WriteFileAtomically(p.string(), Bytes("x"));
  ::umask(old);
  ASSERT_TRUE(s.ok()) << s.message();
  struct stat st;
  ASSERT_EQ(::stat(p.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);  // 0666 less the umask, as open(O_CREAT) makes a file
}

TEST_F(AtomicWriteTest, WritersOnSeveralThreadsEachLandWholeWithNoTemporaryLeft) {
  constexpr int kThreads = 4;
  constexpr int kFiles = 50;
  std::vector<std::thread> threads;
  std::atomic<int> failures{0};
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < kFiles; ++i) {
        // Every thread also rewrites one shared file: each version must land whole.
        const std::string own = "thread " + std::to_string(t) + " file " + std::to_string(i);
        if (!WriteFileAtomically((dir_ / (own + ".txt")).string(), Bytes(own)).ok()) ++failures;
        if (!WriteFileAtomically((dir_ / "shared.txt").string(), Bytes(own)).ok()) ++failures;
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()),
            kThreads * kFiles + 1);
  for (int t = 0; t < kThreads; ++t) {
    for (int i = 0; i < kFiles; ++i) {
      const std::string own = "thread " + std::to_string(t) + " file " + std::to_string(i);
      EXPECT_EQ(Slurp(dir_ / (own + ".txt")), own);
    }
  }
  EXPECT_EQ(Slurp(dir_ / "shared.txt").rfind("thread ", 0), 0u);
}

TEST_F(AtomicWriteTest, AWriteWithItsFlushDeferredStillReplacesTheFileWhole) {
  const fs::path p = dir_ / "frame.pfm";
  std::ofstream(p) << "old";
  ASSERT_TRUE(WriteFileAtomically(p.string(), Bytes("new contents"), Flush::kLater).ok());
  EXPECT_EQ(Slurp(p), "new contents");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
  const Status flushed = FlushFileSystemOf(dir_.string());
  EXPECT_TRUE(flushed.ok()) << flushed.message();
}

TEST_F(AtomicWriteTest, FlushingAMissingDirectoryFailsNamingIt) {
  const std::string missing = (dir_ / "missing").string();
  const Status s = FlushFileSystemOf(missing);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("'" + missing + "'"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("No such file or directory"), std::string::npos) << s.message();
}

TEST_F(AtomicWriteTest, ExportToACharacterDeviceWritesInPlaceAndReportsENOSPC) {
  const std::string dev = FullDevice();
  ASSERT_TRUE(IsCharDevice(dev)) << dev;
  const Status s = WriteFileAtomically(dev, Bytes("model bytes"));
  ASSERT_FALSE(s.ok()) << "a write to " << dev << " reported success";
  EXPECT_NE(s.message().find("cannot write '" + dev + "' (write): No space left on device"),
            std::string::npos)
      << s.message();
  EXPECT_TRUE(IsCharDevice(dev)) << dev << " was replaced";
}

TEST_F(AtomicWriteTest, AtomicWriteToDevNullWritesInPlace) {
  const std::string dev = NullDevice();
  ASSERT_TRUE(IsCharDevice(dev)) << dev;
  ASSERT_TRUE(WriteFileAtomically(dev, Bytes("discarded")).ok());
  EXPECT_TRUE(IsCharDevice(dev)) << dev << " was replaced";
}

TEST_F(AtomicWriteTest, AtomicWriteToAFifoWritesInPlace) {
  const fs::path fifo = dir_ / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // The read end, opened first without blocking, so the writer's open does not wait; the data
  // fits the pipe buffer, so the write does not either. A writer that replaced the FIFO would
  // leave this end empty.
  const int rfd = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
  ASSERT_GE(rfd, 0);
  const Status s = WriteFileAtomically(fifo.string(), Bytes("through the pipe"));
  char buf[64] = {};
  const ssize_t n = ::read(rfd, buf, sizeof(buf));
  ::close(rfd);
  ASSERT_TRUE(s.ok()) << s.message();
  EXPECT_EQ(std::string(buf, n > 0 ? static_cast<size_t>(n) : 0), "through the pipe");
  EXPECT_TRUE(fs::is_fifo(fs::symlink_status(fifo)));
}

TEST_F(AtomicWriteTest, AtomicWriteThroughASymlinkKeepsTheLink) {
  fs::create_directories(dir_ / "results");
  std::ofstream(dir_ / "results" / "flow.npy") << "old";
  fs::create_symlink("results/flow.npy", dir_ / "latest.npy");  // relative to the link's folder
  ASSERT_TRUE(WriteFileAtomically((dir_ / "latest.npy").string(), Bytes("new")).ok());
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(dir_ / "latest.npy")));
  EXPECT_EQ(fs::read_symlink(dir_ / "latest.npy"), fs::path("results/flow.npy"));
  EXPECT_EQ(Slurp(dir_ / "results" / "flow.npy"), "new");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_ / "results"), fs::directory_iterator()), 1);
}

TEST_F(AtomicWriteTest, AtomicWriteThroughADanglingSymlinkCreatesItsTarget) {
  fs::create_symlink(dir_ / "made.txt", dir_ / "link.txt");
  ASSERT_TRUE(WriteFileAtomically((dir_ / "link.txt").string(), Bytes("hello")).ok());
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(dir_ / "link.txt")));
  EXPECT_EQ(Slurp(dir_ / "made.txt"), "hello");
}

TEST_F(AtomicWriteTest, AtomicWriteThroughASymlinkToACharacterDeviceWritesInPlace) {
  const std::string dev = FullDevice();
  fs::create_symlink(dev, dir_ / "full_link");
  const Status s = WriteFileAtomically((dir_ / "full_link").string(), Bytes("x"));
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("No space left on device"), std::string::npos) << s.message();
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(dir_ / "full_link")));
  EXPECT_TRUE(IsCharDevice(dev));
}

TEST_F(AtomicWriteTest, AtomicWriteToADirectoryIsRefusedNamingIt) {
  const Status s = WriteFileAtomically(dir_.string(), Bytes("x"));
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("'" + dir_.string() + "': it is a directory"), std::string::npos)
      << s.message();
}

TEST_F(AtomicWriteTest, AtomicWriteThroughASymlinkLoopIsRefused) {
  fs::create_symlink(dir_ / "b", dir_ / "a");
  fs::create_symlink(dir_ / "a", dir_ / "b");
  const Status s = WriteFileAtomically((dir_ / "a").string(), Bytes("x"));
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("symbolic links"), std::string::npos) << s.message();
}

TEST_F(AtomicWriteTest, StreamedFileToAFullDeviceReportsENOSPCNamingTheFile) {
  const std::string dev = FullDevice();
  Result<StreamedFile> f = StreamedFile::Open(dev);
  ASSERT_TRUE(f.ok()) << f.message();
  const Status s = f->Write("window,source_ms\n");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("cannot write '" + dev + "' (write): No space left on device"),
            std::string::npos)
      << s.message();
  EXPECT_TRUE(IsCharDevice(dev));
}

TEST_F(AtomicWriteTest, StreamedFileWritesARegularFileAsItGoes) {
  const fs::path p = dir_ / "latency.csv";
  std::ofstream(p) << "stale stale stale stale\n";
  Result<StreamedFile> f = StreamedFile::Open(p.string());
  ASSERT_TRUE(f.ok()) << f.message();
  ASSERT_TRUE(f->Write("a,b\n").ok());
  EXPECT_EQ(Slurp(p), "a,b\n");  // truncated at open, no user-space buffer
  ASSERT_TRUE(f->Write("1,2\n").ok());
  ASSERT_TRUE(f->Close().ok());
  EXPECT_EQ(Slurp(p), "a,b\n1,2\n");
}

}  // namespace
}  // namespace sfrt::io
