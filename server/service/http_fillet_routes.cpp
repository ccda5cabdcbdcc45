// Decided fillets: /api/fillets (a page of a query), /api/fillets.csv (every match, for an
// audit), /api/fillets/UID and its images (8-bit views, or the stored record with ?raw=1).
#include <httplib.h>

#include <algorithm>
#include <fstream>
#include <iterator>

#include "core/error.h"
#include "service/fillet_csv.h"
#include "service/http_json.h"
#include "service/http_params.h"
#include "service/http_server.h"
#include "service/image_view.h"

namespace rangex {

using json = nlohmann::json;

void HttpServer::fillet_routes(httplib::Server& s) {
  s.Get("/api/fillets", [this](const httplib::Request& req, httplib::Response& res) {
    const FilletQuery q = fillet_query(req.params);
    json list = json::array();
    int64_t last = q.after;
    for (const StoredFillet& f : store_.list_fillets(q)) {
      list.push_back(fillet_json(f));
      list.back()["images"] = image_kinds(store_, f.uid);
      last = std::max(last, f.uid);
    }
    // `next_after` continues the search where this page ended.
    send_json(res, {{"fillets", list}, {"next_after", last}});
  });
  s.Get("/api/fillets.csv", [this](const httplib::Request& req, httplib::Response& res) {
    auto q = std::make_shared<FilletQuery>(fillet_query(req.params));  // refused here: 400
    q->limit = std::max(1, opt_.csv_page);
    send_csv_pages(
        res, "rangex-fillets.csv", fillet_csv_header(),
        [this, q](std::string& out) {
          const std::vector<StoredFillet> page = store_.list_fillets(*q);
          for (const StoredFillet& f : page) out += fillet_csv_row(f);
          if (int(page.size()) < q->limit) return false;
          q->after = page.back().uid;
          return true;
        },
        stopping_);
  });
  s.Get(R"(/api/fillets/(\d+))", [this](const httplib::Request& req, httplib::Response& res) {
    const int64_t uid = parse_uid(req.matches[1]);
    const std::optional<StoredFillet> f = store_.fillet(uid);
    if (!f) throw NotFound("no fillet " + std::to_string(uid) + " in the store");
    json j = fillet_json(*f);
    j["images"] = image_kinds(store_, uid);
    send_json(res, j);
  });
  s.Get(R"(/api/fillets/(\d+)/images/([a-z_]+))",
        [this](const httplib::Request& req, httplib::Response& res) {
          const int64_t uid = parse_uid(req.matches[1]);
          const std::string kind = checked_image_kind(req.matches[2]);
          const std::optional<std::string> path = store_.image_path(uid, kind);
          if (!path)
            throw NotFound("fillet " + std::to_string(uid) + " has no " + kind +
                           " image (images are kept for rejects and fillets not inspected)");
          std::string body;
          if (kind == "overlay" || req.get_param_value("raw") == "1") {
            std::ifstream in(*path, std::ios::binary);
            if (!in) throw NotFound("image file " + *path + " is missing");
            body.assign(std::istreambuf_iterator<char>(in), {});
          } else {
            body = display_png(*path, kind);
          }
          res.set_header("Cache-Control", "max-age=3600");
          res.set_content(body, "image/png");
        });
}

}  // namespace rangex
