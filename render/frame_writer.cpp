// Writer thread: a bounded queue of frames, written as numbered PNG files and/or one video.
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <exception>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "render/writers.hpp"

namespace lumen::render {

namespace {
constexpr size_t kQueueCapacity = 8;  // frames; push() blocks only when this many are waiting
}  // namespace

struct FrameWriter::Impl {
  std::string frames_dir;
  int width = 0, height = 0;
  std::unique_ptr<VideoEncoder> video;  // null when no video is written

  std::mutex mutex;
  std::condition_variable not_full, not_empty;
  std::deque<Image> queue;           // frames waiting, oldest first
  bool stopping = false;             // no more frames will be pushed
  bool abandon = false;              // destructor without finish(): drop the rest, keep no video
  bool finished = false;
  std::exception_ptr error;          // first error of the writer thread
  WriterStats stats;                 // written by the writer thread, read after join
  long written_index = 0;            // number of the last frame taken from the queue
  std::thread thread;

  void run();
  void write_one(const Image& image, long index);
};

void FrameWriter::Impl::write_one(const Image& image, long index) {
  // One frame: frames_dir/frame_NNNNNN.png (atomic), then the video.
  if (!frames_dir.empty()) {
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%06ld.png", index);
    write_png((std::filesystem::path(frames_dir) / name).string(), image);
  }
  if (video) video->add(image);
}

void FrameWriter::Impl::run() {
  for (;;) {
    // Take the oldest frame, or leave when stopped and drained.
    Image image;
    long index = 0;
    {
      std::unique_lock<std::mutex> lock(mutex);
      not_empty.wait(lock, [this] { return !queue.empty() || stopping; });
      if (queue.empty()) break;
      image = std::move(queue.front());
      queue.pop_front();
      index = ++written_index;
      not_full.notify_one();
      if (error || abandon) continue;  // after a failure frames are dropped so push() never blocks forever
    }
    // Encode and write outside the lock, timing the work.
    const auto t0 = std::chrono::steady_clock::now();
    try {
      write_one(image, index);
      stats.frames += 1;
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      if (!error) error = std::current_exception();
    }
    stats.busy_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  // Finalise the video (flush, trailer, rename) unless abandoned or failed.
  bool finalise = false;
  {
    std::lock_guard<std::mutex> lock(mutex);
    finalise = video && !error && !abandon;
  }
  if (finalise) {
    const auto t0 = std::chrono::steady_clock::now();
    try {
      video->close();
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      if (!error) error = std::current_exception();
    }
    stats.busy_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
}

FrameWriter::FrameWriter(const std::string& frames_dir, const std::string& video_path, int width, int height, int fps)
    : impl_(std::make_unique<Impl>()) {
  // Validate at the boundary: positive size, an existing frames folder; the video encoder checks its own.
  if (width <= 0 || height <= 0)
    throw std::invalid_argument("FrameWriter size must be positive (value " + std::to_string(width) + "x" + std::to_string(height) + ")");
  if (!frames_dir.empty() && !std::filesystem::is_directory(frames_dir))
    throw std::invalid_argument("FrameWriter frames_dir must be an existing folder (value \"" + frames_dir + "\")");
  impl_->frames_dir = frames_dir;
  impl_->width = width;
  impl_->height = height;
  if (!video_path.empty()) impl_->video = std::make_unique<VideoEncoder>(video_path, width, height, fps);
  impl_->thread = std::thread([this] { impl_->run(); });
}

FrameWriter::~FrameWriter() {
  // Without finish(): drop queued frames, stop the thread; the video encoder removes its temporary.
  if (impl_ && impl_->thread.joinable()) {
    {
      std::lock_guard<std::mutex> lock(impl_->mutex);
      impl_->abandon = true;
      impl_->stopping = true;
      impl_->queue.clear();
    }
    impl_->not_empty.notify_all();
    impl_->thread.join();
  }
}

void FrameWriter::push(Image image) {
  Impl& m = *impl_;
  if (image.width != m.width || image.height != m.height || image.rgb.size() != static_cast<size_t>(m.width) * m.height * 3)
    throw std::invalid_argument("FrameWriter::push: image must be " + std::to_string(m.width) + "x" + std::to_string(m.height) +
                                " RGB (value " + std::to_string(image.width) + "x" + std::to_string(image.height) + ", " +
                                std::to_string(image.rgb.size()) + " bytes)");
  // Wait only while the queue is full.
  std::unique_lock<std::mutex> lock(m.mutex);
  if (m.stopping) throw std::logic_error("FrameWriter::push after finish()");
  m.not_full.wait(lock, [&m] { return m.queue.size() < kQueueCapacity; });
  m.queue.push_back(std::move(image));
  m.not_empty.notify_one();
}

WriterStats FrameWriter::finish() {
  Impl& m = *impl_;
  // Let the thread drain the queue and finalise, then report its first error, if any.
  if (!m.finished) {
    {
      std::lock_guard<std::mutex> lock(m.mutex);
      m.stopping = true;
    }
    m.not_empty.notify_all();
    m.thread.join();
    m.finished = true;
  }
  if (m.error) std::rethrow_exception(m.error);
  return m.stats;
}

}  // namespace lumen::render
