// Asynchronous output: one host thread writes queued frames (or any output job) in order while the engine steps.
//
// The engine hands over a ParticleFrame by value (move it: no copy) and goes on stepping; a single worker thread
// runs the jobs first-in first-out, so files appear in submission order. The queue is bounded: when
// `max_pending` jobs wait, submit() blocks until one finishes, so a disk slower than the simulation throttles
// the run instead of exhausting host memory.
//
// Errors are never swallowed: the first job that throws is remembered, every later job is skipped (the run is
// going to stop anyway, and a full disk would fail them all), and the exception is rethrown by the next
// submit(), flush() or close() on the engine's thread, as an OutputError with the job's message. The destructor runs the remaining jobs and joins; since a
// destructor must not throw, an error nobody has been told about yet is printed to std::cerr there. Call close()
// to receive it as an exception.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <filesystem>
#include <functional>
#include <iostream>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include "MnSystem/IO/output_error.h"
#include "MnSystem/IO/particle_io.h"

namespace fbar::io {

class AsyncWriter {
 public:
  /// Starts the worker thread. max_pending >= 1 jobs may wait (not counting the one being written).
  explicit AsyncWriter(std::size_t max_pending = 2) : max_pending_(max_pending < 1 ? 1 : max_pending) {
    worker_ = std::thread([this] { run(); });
  }
  AsyncWriter(const AsyncWriter&) = delete;
  AsyncWriter& operator=(const AsyncWriter&) = delete;
  ~AsyncWriter() {
    stop_worker();
    if (error_ && !error_reported_) std::cerr << "fbar: output error: " << error_message_ << std::endl;
  }

  /// Queues write_frame(path, frame) (format from the suffix). Rethrows an earlier job's error.
  void submit(std::filesystem::path path, ParticleFrame frame) {
    submit_job([path = std::move(path), frame = std::move(frame)] { write_frame(path, frame); });
  }

  /// Queues any output job (sensor CSV rows, run.json, ...). Rethrows an earlier job's error.
  void submit_job(std::function<void()> job) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (closed_) throw std::logic_error("AsyncWriter::submit after close()");
    space_.wait(lock, [this] { return queue_.size() < max_pending_ || error_; });
    rethrow_locked();
    queue_.push_back(std::move(job));
    ++submitted_;
    work_.notify_one();
  }

  /// Blocks until every queued job has run. After a failure every call (submit, flush, close) throws an OutputError:
  /// the first with the job's message, later ones saying that an earlier job failed, with it.
  void flush() {
    std::unique_lock<std::mutex> lock(mutex_);
    idle_.wait(lock, [this] { return queue_.empty() && !busy_; });
    rethrow_locked();
  }

  /// Runs the remaining jobs, then stops the worker thread. Idempotent; rethrows an error like flush().
  void close() {
    stop_worker();
    std::lock_guard<std::mutex> lock(mutex_);
    rethrow_locked();
  }

  /// True once a job has thrown (the next submit, flush or close rethrows it).
  bool failed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return static_cast<bool>(error_);
  }

  /// Jobs finished successfully so far (in order: the first completed() jobs submitted are done).
  std::size_t completed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return completed_;
  }
  /// Jobs submitted so far: after a failure, the jobs up to a count taken at submission are complete when
  /// completed() has reached it.
  std::size_t submitted() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return submitted_;
  }

 private:
  void stop_worker() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
      work_.notify_one();
    }
    if (worker_.joinable()) worker_.join();
  }

  void run() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      work_.wait(lock, [this] { return !queue_.empty() || closed_; });
      if (queue_.empty()) break;  // closed and drained
      std::function<void()> job = std::move(queue_.front());
      queue_.pop_front();
      space_.notify_all();
      if (!error_) {  // after a failure the remaining jobs are skipped
        busy_ = true;
        lock.unlock();
        std::exception_ptr failure;
        std::string message;
        try {
          job();
        } catch (const std::exception& e) {
          failure = std::current_exception();
          message = e.what();
        } catch (...) {
          failure = std::current_exception();
          message = "unknown exception in an output job";
        }
        job = nullptr;  // release the frame's memory outside the lock
        lock.lock();
        busy_ = false;
        if (failure) {
          error_ = failure;
          error_message_ = std::move(message);
          space_.notify_all();  // a submit() blocked on a full queue must see the error
        } else {
          ++completed_;
        }
      }
      if (queue_.empty()) idle_.notify_all();
    }
    idle_.notify_all();
  }

  void rethrow_locked() {
    if (!error_) return;
    if (!error_reported_) {
      error_reported_ = true;
      throw OutputError(error_message_);
    }
    throw OutputError(error_message_, true);
  }

  const std::size_t max_pending_;
  mutable std::mutex mutex_;
  std::condition_variable work_, space_, idle_;
  std::deque<std::function<void()>> queue_;
  std::exception_ptr error_;
  std::string error_message_;
  bool error_reported_ = false;
  bool busy_ = false;
  bool closed_ = false;
  std::size_t completed_ = 0, submitted_ = 0;
  std::thread worker_;
};

}  // namespace fbar::io
