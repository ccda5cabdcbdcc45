#include "sensors/fake_devices.h"

#include <arpa/inet.h>
#include <arv.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <set>
#include <stdexcept>

namespace rangex {

namespace {

std::set<std::string> interface_addresses() {
  std::set<std::string> out;
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return out;
  for (ifaddrs* a = list; a; a = a->ifa_next) {
    if (!a->ifa_addr || a->ifa_addr->sa_family != AF_INET) continue;
    char b[INET_ADDRSTRLEN];
    inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(a->ifa_addr)->sin_addr, b, sizeof b);
    out.insert(b);
  }
  freeifaddrs(list);
  return out;
}

int ip(const std::string& verb, const std::string& address) {
  const std::string sudo = geteuid() == 0 ? "" : "sudo -n ";
  const std::string cmd = sudo + "ip addr " + verb + " " + address + "/32 dev lo 2>/dev/null";
  return std::system(cmd.c_str());
}

}  // namespace

LoopbackAddresses::LoopbackAddresses(std::vector<std::string> addresses) {
  const std::set<std::string> have = interface_addresses();
  for (const std::string& a : addresses) {
    if (have.count(a)) continue;
    if (ip("add", a) != 0) {
      error_ = "cannot add " + a + " to lo (ip addr add needs root or passwordless sudo)";
      return;
    }
    added_.push_back(a);
  }
}

LoopbackAddresses::~LoopbackAddresses() {
  for (const std::string& a : added_) ip("del", a);
}

ServedLane::ServedLane(const RecordingReader& rec, int lane, int lead_frames)
    : frames_(rec.map_frames(lane)), lead_(lead_frames) {
  const RecordingInfo& info = rec.info();
  frame_bytes_ = size_t(info.width) * size_t(info.height);
  xray_pixels_ = size_t(info.xray_pixels);
  energies_ = info.xray_energies == 2 ? 2 : 1;
  lines_ = info.lines;
  // Per line the detector's frame: the low row, then (two energies) the high row.
  std::vector<uint16_t> low(xray_pixels_ * size_t(lines_)), high;
  rec.read(lane, 0, lines_, nullptr, nullptr, low.data(), nullptr);  // frames stay mapped
  if (energies_ == 2) {
    high.resize(low.size());
    rec.read_high(lane, 0, lines_, high.data());
  }
  xray_.resize(xray_pixels_ * size_t(energies_) * size_t(lines_));
  for (int64_t l = 0; l < lines_; ++l) {
    uint16_t* row = &xray_[xray_pixels_ * size_t(energies_) * size_t(l)];
    std::copy_n(&low[xray_pixels_ * size_t(l)], xray_pixels_, row);
    if (energies_ == 2)
      std::copy_n(&high[xray_pixels_ * size_t(l)], xray_pixels_, row + xray_pixels_);
  }
}

const uint8_t* ServedLane::frame(int d, int64_t line) const {
  line = std::clamp<int64_t>(line, 0, lines_ - 1);
  if (d < 2) return frames_.frame(d, line);
  return reinterpret_cast<const uint8_t*>(&xray_[xray_pixels_ * size_t(energies_) * size_t(line)]);
}

void ServedLane::fill(int d, int64_t n, uint8_t* out, size_t bytes) {
  const size_t want = d < 2 ? frame_bytes_ : xray_pixels_ * 2 * size_t(energies_);
  std::memcpy(out, frame(d, n - lead_), std::min(bytes, want));
}

struct FakeDevice::Impl {
  ArvGvFakeCamera* gv = nullptr;
  Fill fill;
  int64_t frames = 0;  // filled so far (the fake's thread alone calls fill_frame)
};

namespace {

void fill_frame(ArvBuffer* b, void* data, guint32, guint32, ArvPixelFormat pf) {
  auto* d = static_cast<FakeDevice::Impl*>(data);
  size_t ignored = 0;  // Aravis 0.8.26 reports 0 here; the image's size gives it
  auto* p = static_cast<uint8_t*>(const_cast<void*>(arv_buffer_get_data(b, &ignored)));
  const size_t bytes = size_t(arv_buffer_get_image_width(b)) *
                       size_t(arv_buffer_get_image_height(b)) *
                       (ARV_PIXEL_FORMAT_BIT_PER_PIXEL(pf) / 8);
  d->fill(d->frames++, p, bytes);
}

}  // namespace

FakeDevice::FakeDevice(const std::string& address, const std::string& serial, int period_us,
                       Fill fill, const std::string& genicam_file)
    : impl_(std::make_unique<Impl>()) {
  impl_->fill = std::move(fill);
  impl_->gv = arv_gv_fake_camera_new_full(address.c_str(), serial.c_str(),
                                          genicam_file.empty() ? nullptr : genicam_file.c_str());
  if (!impl_->gv || !arv_gv_fake_camera_is_running(impl_->gv))
    throw std::runtime_error("fake GigE Vision device on " + address + " did not start");
  ArvFakeCamera* cam = arv_gv_fake_camera_get_fake_camera(impl_->gv);
  arv_fake_camera_write_register(cam, ARV_FAKE_CAMERA_REGISTER_ACQUISITION_FRAME_PERIOD_US,
                                 guint32(period_us));
  arv_fake_camera_set_trigger_frequency(cam, 1e6 / period_us);
  arv_fake_camera_set_fill_pattern(cam, fill_frame, impl_.get());
}

FakeDevice::~FakeDevice() {
  if (impl_->gv) g_object_unref(impl_->gv);
}

void FakeDevice::set_packet_loss(double ratio) {
  g_object_set(impl_->gv, "gvsp-lost-ratio", ratio, nullptr);
}

void FakeDevice::set_genicam_url(const std::string& url) {
  if (url.size() >= 512) throw std::runtime_error("a GenICam URL register holds 511 bytes");
  arv_fake_camera_write_memory(arv_gv_fake_camera_get_fake_camera(impl_->gv), 0x200,
                               guint32(url.size() + 1), url.c_str());
}

void FakeDevice::trigger() {
  arv_fake_camera_write_register(arv_gv_fake_camera_get_fake_camera(impl_->gv),
                                 ARV_FAKE_CAMERA_REGISTER_TRIGGER_SOFTWARE, 1);
}

bool FakeDevice::trigger_pending() const {
  guint32 v = 0;
  arv_fake_camera_read_register(arv_gv_fake_camera_get_fake_camera(impl_->gv),
                                ARV_FAKE_CAMERA_REGISTER_TRIGGER_SOFTWARE, &v);
  return v != 0;
}

bool FakeDevice::acquiring() const {
  ArvFakeCamera* cam = arv_gv_fake_camera_get_fake_camera(impl_->gv);
  return arv_fake_camera_get_control_channel_privilege(cam) != 0 &&
         arv_fake_camera_get_acquisition_status(cam) != 0 &&
         arv_fake_camera_is_in_software_trigger_mode(cam);
}

FakeEncoder::FakeEncoder(std::vector<std::unique_ptr<FakeDevice>>& devices) : devices_(devices) {
  thread_ = std::thread([this] {
    bool first = true;
    while (!stop_) {
      {
        std::lock_guard<std::mutex> lk(mu_);
        bool ready = true;
        for (auto& d : devices_) ready = ready && (!d || d->acquiring());
        if (!ready) {
          std::this_thread::sleep_for(std::chrono::milliseconds(2));
          continue;
        }
        if (!first) ++pulses_;
        first = false;
        for (auto& d : devices_)
          if (d) d->trigger();
        const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
        while (!stop_ && std::chrono::steady_clock::now() < end) {
          bool taken = true;
          for (auto& d : devices_)
            if (d && d->acquiring() && d->trigger_pending()) taken = false;
          if (taken) break;
          std::this_thread::sleep_for(std::chrono::microseconds(300));
        }
      }
      std::this_thread::sleep_for(std::chrono::microseconds(300));
    }
  });
}

FakeEncoder::~FakeEncoder() {
  stop_ = true;
  thread_.join();
}

void FakeEncoder::replace(size_t d, std::unique_ptr<FakeDevice> device) {
  std::lock_guard<std::mutex> lk(mu_);
  devices_[d] = std::move(device);
}

std::string FakeDevice::genicam_xml() {
  ArvFakeCamera* cam = arv_fake_camera_new("xml");
  size_t size = 0;
  const char* xml = arv_fake_camera_get_genicam_xml(cam, &size);
  std::string out(xml, size);
  g_object_unref(cam);
  return out;
}

}  // namespace rangex
