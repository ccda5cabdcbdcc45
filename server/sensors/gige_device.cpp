#include "sensors/gige_device.h"

#include <arpa/inet.h>
#include <arv.h>

#include <algorithm>
#include <atomic>
#include <mutex>

#include "core/error.h"
#include "core/log.h"
#include "core/text_file.h"
#include "sensors/frame_counts.h"
#include "sensors/genicam_url.h"
#include "sensors/genicam_zip.h"
#include "sensors/gvcp_read.h"
#include "sensors/hex_text.h"

namespace rangex {

namespace {

// A GError into a message, freed.
std::string take_error(GError*& e) {
  std::string m = e ? e->message : "no reason given";
  g_clear_error(&e);
  return m;
}

// The stream and the buffers popped from it: a line that still holds a buffer when the
// device has gone gives it back to nothing (the buffer is freed with its last reference).
struct Session {
  std::mutex mu;
  ArvStream* stream = nullptr;  // null once closed
  void give_back(ArvBuffer* b) {
    std::lock_guard<std::mutex> lk(mu);
    if (stream)
      arv_stream_push_buffer(stream, b);
    else
      g_object_unref(b);
  }
};

// The device's IPv4 address: the id itself, or what Aravis's discovery gives for it.
std::optional<std::string> device_ipv4(const std::string& id) {
  in_addr a{};
  if (inet_pton(AF_INET, id.c_str(), &a) == 1) return id;
  arv_update_device_list();
  for (unsigned i = 0; i < arv_get_n_devices(); ++i)
    for (const char* name :
         {arv_get_device_id(i), arv_get_device_physical_id(i), arv_get_device_serial_nbr(i)}) {
      const char* address = arv_get_device_address(i);
      if (name && id == name && address && inet_pton(AF_INET, address, &a) == 1) return address;
    }
  return std::nullopt;
}

// What the device names as its GenICam description, checked before Aravis reads it whole.
void check_description(const std::string& id) {
  const std::optional<std::string> ip = device_ipv4(id);
  if (!ip) return;  // not on the network: arv_camera_new says so
  std::string text = gvcp_read_memory(*ip, kGvcpXmlUrl0, kGvcpReadMax);
  text.resize(std::min(text.find('\0'), text.size()));
  GenicamUrl url;
  try {
    url = parse_genicam_url(text);
  } catch (const Error& e) {
    fail("device ", id, ": ", e.what());
  }
  std::string why = genicam_url_refusal(url);
  if (why.empty() && genicam_is_zip(url.path))
    why = genicam_zip_refusal(url.scheme == "local"
                                  ? gvcp_read_range(*ip, url.address, url.size)
                                  : read_text_file(url.path, "a GenICam description"));
  if (!why.empty())
    fail("device ", id, " names its GenICam description '", text.substr(0, 120), "': refused, ",
         why);
}

void on_control_lost(ArvDevice*, gpointer flag) {
  static_cast<std::atomic<bool>*>(flag)->store(true);
}

}  // namespace

const char* role_name(DeviceRole r, int index) {
  if (r == DeviceRole::kXray) return "xray";
  return index == 0 ? "cam0" : "cam1";
}

struct GigeDevice::Impl {
  DeviceSetup setup;
  ArvCamera* camera = nullptr;
  ArvChunkParser* chunks = nullptr;  // when the device sends its encoder value
  std::shared_ptr<Session> session = std::make_shared<Session>();
  std::atomic<bool> control_lost{false};
  gulong lost_handler = 0;
  ArvPixelFormat format = 0;
  uint64_t frames = 0;
  FrameIdGaps gaps;
  std::string description;

  [[noreturn]] void refused(const char* feature, const std::string& value, GError*& e) {
    fail("device ", setup.id, " refuses ", feature, "=", value, ": ", take_error(e));
  }
  void set_int(const char* feature, int64_t v) {
    GError* e = nullptr;
    arv_camera_set_integer(camera, feature, v, &e);
    if (e) refused(feature, std::to_string(v), e);
    const int64_t got = arv_camera_get_integer(camera, feature, &e);
    if (e) refused(feature, std::to_string(v), e);
    if (got != v) fail("device ", setup.id, " refuses ", feature, "=", v, ": it keeps ", got);
  }
  void set_string(const char* feature, const char* v) {
    GError* e = nullptr;
    arv_camera_set_string(camera, feature, v, &e);
    if (e) refused(feature, v, e);
  }
  bool has(const char* feature) {
    GError* e = nullptr;
    const bool yes = arv_camera_is_feature_available(camera, feature, &e);
    g_clear_error(&e);
    return yes;
  }

  void open() {
    check_description(setup.id);
    GError* e = nullptr;
    camera = arv_camera_new(setup.id.c_str(), &e);
    if (!camera) fail("device ", setup.id, " cannot be opened: ", take_error(e));
    if (!arv_camera_is_gv_device(camera)) fail("device ", setup.id, " is not a GigE Vision device");
    const char* vendor = arv_camera_get_vendor_name(camera, &e);
    g_clear_error(&e);
    const char* model = arv_camera_get_model_name(camera, &e);
    g_clear_error(&e);
    const char* serial = arv_camera_get_device_serial_number(camera, &e);
    g_clear_error(&e);
    description =
        join(vendor ? vendor : "?", " ", model ? model : "?", " #", serial ? serial : "?");
    lost_handler = g_signal_connect(arv_camera_get_device(camera), "control-lost",
                                    G_CALLBACK(on_control_lost), &control_lost);
  }

  void configure() {
    GError* e = nullptr;
    // The window first at offset 0, so that a height the sensor allows only at a smaller
    // offset is not refused for the old offset.
    if (has("OffsetY") && setup.offset_y >= 0) set_int("OffsetY", 0);
    set_int("Width", setup.width);
    set_int("Height", setup.height);
    if (setup.offset_y >= 0) set_int("OffsetY", setup.offset_y);
    const char* pf = setup.role == DeviceRole::kXray ? "Mono16" : "Mono8";
    set_string("PixelFormat", pf);
    format = arv_camera_get_pixel_format(camera, &e);
    if (e) refused("PixelFormat", pf, e);
    const ArvPixelFormat want =
        setup.role == DeviceRole::kXray ? ARV_PIXEL_FORMAT_MONO_16 : ARV_PIXEL_FORMAT_MONO_8;
    if (format != want)
      fail("device ", setup.id, " refuses PixelFormat=", pf, ": it keeps ", hex32(format));
    arv_camera_set_acquisition_mode(camera, ARV_ACQUISITION_MODE_CONTINUOUS, &e);
    if (e) refused("AcquisitionMode", "Continuous", e);
    if (has("TriggerSelector")) set_string("TriggerSelector", "FrameStart");
    if (setup.trigger == LineTrigger::kEncoder) {
      set_string("TriggerMode", "On");
      set_string("TriggerSource", setup.trigger_line.c_str());
      // The encoder value in each frame's chunk, where the device has it.
      if (has("ChunkEncoderValue") && has("ChunkModeActive")) {
        arv_camera_set_chunks(camera, "EncoderValue", &e);
        if (e) refused("ChunkSelector", "EncoderValue", e);
        chunks = arv_camera_create_chunk_parser(camera);
      }
    } else if (has("TriggerMode")) {
      set_string("TriggerMode", "Off");
    }
    if (setup.exposure_us > 0) {
      arv_camera_set_exposure_time(camera, setup.exposure_us, &e);
      if (e) refused("ExposureTime", std::to_string(setup.exposure_us), e);
    }
    if (setup.packet_size > 0) {
      arv_camera_gv_set_packet_size(camera, setup.packet_size, &e);
      if (e) refused("GevSCPSPacketSize", std::to_string(setup.packet_size), e);
    } else {
      // The largest the path carries; a device without the test packet keeps its own.
      arv_camera_gv_auto_packet_size(camera, &e);
      if (e)
        log::info("sensor_packet_size", "device {} keeps its packet size: {}", setup.id,
                  take_error(e));
    }
  }

  void start() {
    GError* e = nullptr;
    // The socket path, not Aravis's packet socket (taken where rangexd may open one, e.g. as
    // root): that socket hears every device on the host until its filter is attached, and a
    // device starting beside streaming ones took their frames as its own.
    arv_camera_gv_set_stream_options(camera, ARV_GV_STREAM_OPTION_PACKET_SOCKET_DISABLED);
    ArvStream* stream = arv_camera_create_stream(camera, nullptr, nullptr, &e);
    if (!stream) fail("device ", setup.id, " gives no stream: ", take_error(e));
    const guint payload = arv_camera_get_payload(camera, &e);
    if (e) fail("device ", setup.id, " gives no payload size: ", take_error(e));
    // Each receive buffer is allocated at the payload size the device gives: it must hold
    // one frame, and be no more than a frame and its chunks (a device giving gigabytes would
    // have that much reserved a buffer).
    const size_t frame = frame_bytes();
    if (payload < frame || payload > 2 * frame + (64u << 10))
      fail("device ", setup.id, " gives a payload size of ", payload, " bytes for frames of ",
           setup.width, "x", setup.height, " ", hex32(format), " (", frame,
           " bytes): refused, it must hold one frame and its chunks, at most ", 2 * frame,
           " + 65536 bytes");
    // The socket's receive buffer for every receive buffer's frame, 1 MiB at least; the kernel
    // holds it to net.core.rmem_max (docs/sensors.md). Aravis's "auto" sizes it to one frame:
    // an X-ray line of 960 bytes then left no room for its own three packets.
    if (ARV_IS_GV_STREAM(stream)) {
      const size_t want = std::max<size_t>(size_t(payload) * size_t(setup.buffers), 1u << 20);
      g_object_set(stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED, "socket-buffer-size",
                   gint(std::min<size_t>(want, 1u << 30)), nullptr);
    }
    for (int i = 0; i < setup.buffers; ++i)
      arv_stream_push_buffer(stream, arv_buffer_new_allocate(payload));
    session->stream = stream;
    arv_camera_start_acquisition(camera, &e);
    if (e) refused("AcquisitionStart", "1", e);
  }

  size_t frame_bytes() const {
    return size_t(setup.width) * size_t(setup.height) *
           (format == ARV_PIXEL_FORMAT_MONO_16 ? 2 : 1);
  }

  void close() {
    if (camera && !control_lost) {
      GError* e = nullptr;
      arv_camera_stop_acquisition(camera, &e);
      g_clear_error(&e);
    }
    {
      std::lock_guard<std::mutex> lk(session->mu);
      if (session->stream) g_object_unref(session->stream);
      session->stream = nullptr;
    }
    if (chunks) g_object_unref(chunks);
    if (camera) {
      if (lost_handler) g_signal_handler_disconnect(arv_camera_get_device(camera), lost_handler);
      g_object_unref(camera);
    }
    camera = nullptr;
    chunks = nullptr;
  }
};

GigeDevice::GigeDevice(const DeviceSetup& setup) : impl_(std::make_unique<Impl>()) {
  impl_->setup = setup;
  try {
    impl_->open();
    impl_->configure();
    impl_->start();
  } catch (...) {
    impl_->close();
    throw;
  }
}

GigeDevice::~GigeDevice() {
  impl_->close();
}

GigeDevice::Got GigeDevice::next(int timeout_ms, DeviceFrame& out, std::string& why) {
  Impl& d = *impl_;
  ArvStream* stream = d.session->stream;
  ArvBuffer* b = arv_stream_timeout_pop_buffer(stream, guint64(timeout_ms) * 1000);
  if (!b) return Got::kNothing;
  const uint64_t id = arv_buffer_get_frame_id(b);
  if (arv_buffer_get_status(b) != ARV_BUFFER_STATUS_SUCCESS || id == 0) {
    // GVSP never sends id 0: such a buffer holds no frame of the device and takes no count
    // (counted, it would move every later count one on and hide the id gaps after it).
    if (id != 0) d.frames += 1 + d.gaps.next(id);
    arv_stream_push_buffer(stream, b);
    return Got::kIncomplete;
  }
  const ArvPixelFormat pf = arv_buffer_get_image_pixel_format(b);
  const int w = arv_buffer_get_image_width(b), h = arv_buffer_get_image_height(b);
  if (pf != d.format || w != d.setup.width || h != d.setup.height) {
    why = join("frame of ", w, "x", h, " pixel format ", hex32(pf), " (expected ", d.setup.width,
               "x", d.setup.height, " ", hex32(d.format), ")");
    arv_stream_push_buffer(stream, b);
    return Got::kWrongFormat;
  }
  out.id = id;
  out.lost_before = d.gaps.next(id);
  d.frames += 1 + out.lost_before;
  out.count = int64_t(d.frames);
  out.from_encoder = false;
  if (d.chunks && arv_buffer_has_chunks(b)) {
    GError* e = nullptr;
    const gint64 v = arv_chunk_parser_get_integer_value(d.chunks, b, "ChunkEncoderValue", &e);
    if (!e) {
      out.count = v;
      out.from_encoder = true;
    }
    g_clear_error(&e);
  }
  // The X-ray line's Mono16 is little-endian (PFNC), as the lane takes it: no conversion.
  size_t size = 0;
  const void* data = arv_buffer_get_data(b, &size);
  if (size < d.frame_bytes()) {  // a leader's size the data did not fill
    why = join("frame of ", size, " bytes for ", w, "x", h, " ", hex32(pf), " (", d.frame_bytes(),
               " bytes)");
    arv_stream_push_buffer(stream, b);
    return Got::kWrongFormat;
  }
  size = d.frame_bytes();  // without any chunk data after the image
  std::shared_ptr<Session> s = d.session;
  std::shared_ptr<void> keep(b, [s](void* p) { s->give_back(static_cast<ArvBuffer*>(p)); });
  out.bytes = LineBytes::lent(static_cast<char*>(const_cast<void*>(data)), size, std::move(keep));
  return Got::kFrame;
}

bool GigeDevice::answering() {
  if (impl_->control_lost) return false;
  guint32 v = 0;
  GError* e = nullptr;
  // The bootstrap's version register: every GigE Vision device has it.
  const bool ok = arv_device_read_register(arv_camera_get_device(impl_->camera), 0x0000, &v, &e);
  g_clear_error(&e);
  if (!ok) impl_->control_lost = true;  // nothing more is asked of it (no stop command)
  return ok;
}

DeviceStreamCounts GigeDevice::stream_counts() const {
  DeviceStreamCounts c;
  ArvStream* s = impl_->session->stream;
  if (s) arv_stream_get_statistics(s, &c.completed, &c.failures, &c.underruns);
  return c;
}

const std::string& GigeDevice::description() const {
  return impl_->description;
}

}  // namespace rangex
