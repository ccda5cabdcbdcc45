// How the server takes lines in and watches itself (plant.yaml `server:`). The defaults
// suit a plant of up to 16 lanes at 2.5 k lines/s each.
#pragma once
#include <cstddef>

namespace rangex {

struct EngineSettings {
  size_t queue_lines = 2048;  // lines waiting for the worker, all lanes together
  int batch_lines = 64;
  int batch_wait_ms = 10;  // a partial batch goes after this long
  // Threads inspecting cut fillets, each lane's in order: fillets of lanes that close
  // together are inspected side by side instead of one after another.
  int inspectors = 2;
  // Counts behind a lane's latest within which a resent line is recognised as already
  // accepted (DUPLICATE_LINE); must cover what a feeder can have unacknowledged.
  int dedup_window = 4096;
  // A line further behind than the window is an encoder reset (a restarted PLC or camera):
  // the lane restarts at it. Off: such lines are refused until ControlService.ResetLane.
  bool auto_reset = true;
  // A lane with a fillet open and no line for this long ends it as not inspected.
  double idle_close_s = 30;
  // Lines queued and the worker making no progress this long: health says NOT_SERVING.
  double stall_s = 5;
  // NOT_SERVING this long: rangexd exits non-zero so that its supervisor restarts it (0: never).
  double exit_after_s = 60;
  // An ingest stream with no request this long is closed (UNAVAILABLE, naming why); a feeder
  // reconnects when it has lines again. Streams that never send would otherwise be held
  // for ever.
  double stream_idle_s = 300;
  // Result subscriptions over gRPC at once (dashboards, reject gates, `rangexctl watch`).
  // When full, the one furthest behind (more than 16 results waiting: a client that stopped
  // reading) gives way to a new one; with none behind, a new one is refused
  // (RESOURCE_EXHAUSTED). Each holds up to 256 results waiting for it.
  int max_subscriptions = 64;
  // Ingest streams at once. Each costs about 20 kB held (20,000 took rangexd from 100 to
  // 490 MB); a plant needs one a feeder, and a stream left by a feeder that went is closed
  // after stream_idle_s. When full, the one with no request for longest gives way to a new
  // one if that is at least stream_gives_way_s (a leaked stream; a feeder whose belt stands
  // reconnects when it has lines); streams that feed are never cut for it. With none so
  // quiet, a new one is refused (RESOURCE_EXHAUSTED) and a feeder tries again.
  int max_ingest_streams = 256;
  double stream_gives_way_s = 30;
  // What gRPC may hold for the gRPC port's connections, all together: messages as they
  // arrive and the connections' buffers. gRPC holds a message whole before it checks its
  // size (up to 4 GiB, whatever the bound), so without this one client could take the
  // server's memory. Past it gRPC cancels streams (RESOURCE_EXHAUSTED) until it is under
  // again; feeders reconnect and resend. A 4-lane plant fed at full speed holds under 16 MB.
  int grpc_memory_mb = 256;
  // Statistics warn when the store's volume has less free than this, before a full disk
  // stops the store (0: never).
  double store_reserve_mb = 1024;
  // A graceful stop that cannot decide the queued lines in this long exits non-zero.
  double drain_timeout_s = 30;
  // Of the batches a device backend computes, the fraction recomputed on the CPU reference
  // and compared (0: none; 1: every batch).
  double verify_fraction = 0.01;
};

}  // namespace rangex
