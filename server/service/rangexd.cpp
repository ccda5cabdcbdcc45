// rangexd: the inspection server. Loads the plant configuration, opens its store, serves
// rangex.v1 over gRPC (loopback by default) until SIGINT/SIGTERM, then drains and stops.
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>

#include "core/error.h"
#include "service/server.h"

namespace {
volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

constexpr const char* kUsage =
    "usage: rangexd [--config PLANT.yaml] [--listen HOST:PORT] [--data DIR] [--threads N]\n"
    "               [--queue LINES] [--batch LINES]\n";
}  // namespace

int main(int argc, char** argv) {
  std::string config, listen, data;
  rangex::EngineOptions eng;
  eng.threads = int(std::max(1u, std::thread::hardware_concurrency()));
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "rangexd: %s needs a value\n%s", a.c_str(), kUsage);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--config")
      config = value();
    else if (a == "--listen")
      listen = value();
    else if (a == "--data")
      data = value();
    else if (a == "--threads")
      eng.threads = std::stoi(value());
    else if (a == "--queue")
      eng.queue_capacity = std::stoul(value());
    else if (a == "--batch")
      eng.batch_lines = std::stoi(value());
    else if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    } else {
      std::fprintf(stderr, "rangexd: unknown option %s\n%s", a.c_str(), kUsage);
      return 2;
    }
  }
  if (config.empty()) {
    if (const char* env = std::getenv("RANGEX_CONFIG"))
      config = env;
    else
      config = std::filesystem::exists("config/plant.yaml") ? "config/plant.yaml"
                                                            : RANGEX_DEFAULT_CONFIG;
  }
  try {
    const rangex::PlantConfig plant = rangex::load_plant_config(config);
    rangex::ServerOptions opt;
    opt.listen = listen;
    opt.data_dir = data;
    opt.engine = eng;
    rangex::RangexServer server(plant, opt);
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    std::printf("rangexd: plant '%s', %zu lanes, backend cpu, listening on %s, store %s\n",
                plant.name.c_str(), plant.lanes.size(), server.address().c_str(),
                (data.empty() ? plant.storage : data).c_str());
    std::fflush(stdout);
    while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    std::printf("rangexd: stopping: draining queued lines and closing open fillets\n");
    server.shutdown();
    const auto s = server.engine().stats();
    std::printf("rangexd: stopped after %llu lines, %llu fillets\n",
                (unsigned long long)s.processed, (unsigned long long)s.fillets);
    return 0;
  } catch (const rangex::Error& e) {
    std::fprintf(stderr, "rangexd: error: %s\n", e.what());
    return 1;
  }
}
