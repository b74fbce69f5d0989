// A persistent worker thread: runs the jobs given to it, one at a time, in order.
//
// Why not std::async: it starts a new thread per call, and OpenCV keeps the thread-local data
// of every thread that ever called it (its trace and TLS bookkeeping outlive the thread), about
// 0.8 KB per thread. A per-frame std::async therefore grows the heap for as long as the
// pipeline runs; a worker that lives as long as its owner does not.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <thread>
#include <type_traits>

namespace treestereo {

class Worker {
public:
  Worker();
  // Waits for the queued jobs, then joins the thread.
  ~Worker();
  Worker(const Worker &) = delete;
  Worker &operator=(const Worker &) = delete;

  // Queues @job; its result (or exception) arrives through the future.
  template <class F> auto run(F job) -> std::future<std::invoke_result_t<F>>
  {
    using R = std::invoke_result_t<F>;
    auto task = std::make_shared<std::packaged_task<R()>>(std::move(job));
    std::future<R> result = task->get_future();
    post([task] { (*task)(); });
    return result;
  }

  std::thread::id id() const { return thread_.get_id(); }

private:
  void post(std::function<void()> job);
  void loop();

  std::mutex lock_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> jobs_;
  bool stop_ = false;
  std::thread thread_; // last: starts once the members above exist
};

// Waits for a job's end when it goes out of scope, also when an exception leaves the scope: a job
// that reads the caller's data (a frame, its state) must end before that data goes.
template <class T> class WaitFor {
public:
  explicit WaitFor(std::future<T> &job) : job_(job) {}
  WaitFor(const WaitFor &) = delete;
  WaitFor &operator=(const WaitFor &) = delete;
  ~WaitFor()
  {
    if (job_.valid())
      job_.wait();
  }

private:
  std::future<T> &job_;
};

} // namespace treestereo
