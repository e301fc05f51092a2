// libcamera probe for the VM tests, against the vimc test driver.
//
//   stemd-vm-libcamera-probe [ID_SUBSTRING]
//       starts a CameraManager, lists the cameras, picks the first whose id
//       contains ID_SUBSTRING (default "vimc"), configures a viewfinder stream
//       and captures frames until one completes; checks the request and frame
//       completed, the frame has bytes, and they are not all one value.
#include <sys/mman.h>

#include <libcamera/libcamera.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "probe_util.hpp"

namespace {

using stemd::vmprobe::fail;
using stemd::vmprobe::fail_errno;
using stemd::vmprobe::info;

// Collects completed requests; libcamera calls done() from its own thread.
class Completions {
 public:
  void done(libcamera::Request* request) {
    std::lock_guard lock(mutex_);
    completed_.push_back(request);
    cv_.notify_all();
  }
  libcamera::Request* wait(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    if (!cv_.wait_for(lock, timeout, [this] { return !completed_.empty(); })) return nullptr;
    libcamera::Request* r = completed_.front();
    completed_.erase(completed_.begin());
    return r;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<libcamera::Request*> completed_;
};

// Stops the camera manager on every exit path (cameras must be released first).
struct ManagerStopper {
  void operator()(libcamera::CameraManager* cm) const {
    cm->stop();
    delete cm;
  }
};

// Checks the pixels of one single-plane frame are not all the same value.
void check_not_constant(const libcamera::FrameBuffer& buffer, unsigned bytesused, const std::string& camera) {
  const auto& plane = buffer.planes().front();
  const std::size_t length = plane.offset + plane.length;
  void* map = ::mmap(nullptr, length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
  if (map == MAP_FAILED) fail_errno(camera, "mmap of the frame buffer");
  const auto* p = static_cast<const std::uint8_t*>(map) + plane.offset;
  std::size_t differing = 0;
  for (unsigned i = 1; i < bytesused && i < plane.length; ++i) differing += p[i] != p[0];
  ::munmap(map, length);
  if (differing == 0) fail(camera + ": frame is one constant byte");
}

void probe(const std::string& wanted) {
  std::unique_ptr<libcamera::CameraManager, ManagerStopper> cm;
  {
    auto manager = std::make_unique<libcamera::CameraManager>();
    const int r = manager->start();
    if (r < 0) {
      errno = -r;
      fail_errno("libcamera", "CameraManager::start");
    }
    cm.reset(manager.release());
  }
  info("libcamera " + libcamera::CameraManager::version());
  std::shared_ptr<libcamera::Camera> camera;
  for (const auto& c : cm->cameras()) {
    info("camera: " + c->id());
    if (!camera && c->id().find(wanted) != std::string::npos) camera = c;
  }
  if (!camera) fail("no camera whose id contains '" + wanted + "' (is the udev database faked?)");
  const std::string id = camera->id();

  if (camera->acquire() < 0) fail("cannot acquire " + id);
  // Release before the manager stops, whatever happens below.
  std::unique_ptr<libcamera::Camera, void (*)(libcamera::Camera*)> held(camera.get(),
                                                                         [](libcamera::Camera* c) { c->release(); });

  auto config = camera->generateConfiguration({libcamera::StreamRole::Viewfinder});
  if (!config || config->size() != 1) fail(id + ": no viewfinder configuration");
  if (config->validate() == libcamera::CameraConfiguration::Invalid) fail(id + ": configuration invalid");
  if (camera->configure(config.get()) < 0) fail(id + ": configure failed");
  libcamera::StreamConfiguration& sc = config->at(0);
  info("stream " + sc.toString());

  libcamera::FrameBufferAllocator allocator(camera);
  if (allocator.allocate(sc.stream()) < 0) fail(id + ": buffer allocation failed");
  std::vector<std::unique_ptr<libcamera::Request>> requests;
  for (const auto& buffer : allocator.buffers(sc.stream())) {
    auto request = camera->createRequest();
    if (!request || request->addBuffer(sc.stream(), buffer.get()) < 0) fail(id + ": cannot build a request");
    requests.push_back(std::move(request));
  }
  if (requests.empty()) fail(id + ": no buffers");

  Completions completions;
  camera->requestCompleted.connect(&completions, &Completions::done);
  if (camera->start() < 0) fail(id + ": start failed");
  struct Stop {
    libcamera::Camera* c;
    ~Stop() { c->stop(); }
  } stop{camera.get()};
  for (auto& request : requests) {
    if (camera->queueRequest(request.get()) < 0) fail(id + ": queueRequest failed");
  }
  // vimc is slow under emulation: allow several seconds for the first frame.
  libcamera::Request* done = completions.wait(std::chrono::seconds(15));
  if (done == nullptr) fail(id + ": no request completed within 15 s");
  if (done->status() != libcamera::Request::RequestComplete) fail(id + ": request did not complete (cancelled)");
  libcamera::FrameBuffer* buffer = done->buffers().begin()->second;
  const auto& meta = buffer->metadata();
  if (meta.status != libcamera::FrameMetadata::FrameSuccess) fail(id + ": frame status is not success");
  const unsigned bytes = meta.planes().empty() ? 0 : meta.planes()[0].bytesused;
  if (bytes == 0) fail(id + ": frame has no bytes");
  check_not_constant(*buffer, bytes, id);
  info("captured frame seq=" + std::to_string(meta.sequence) + " bytes=" + std::to_string(bytes) + " from " + id);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string wanted = argc > 1 ? argv[1] : "vimc";
  return stemd::vmprobe::run_probe("libcamera-probe", [&] { probe(wanted); });
}
