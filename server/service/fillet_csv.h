// Stored fillets as CSV, one row per fillet, for an audit (the dashboard's records export):
// what was decided, when, by which calibration, with the fit and every fragment found.
#pragma once
#include <atomic>
#include <functional>
#include <string>
#include <vector>

#include "store/store.h"

namespace httplib {
struct Response;
}

namespace rangex {

// Rows a page of an export: what an export holds in memory at once (about 1 MB).
constexpr int kCsvPage = 5000;

std::string fillet_csv_header();
std::string fillet_csv_row(const StoredFillet& f);

// Sends a CSV export page by page as the reader takes it (chunked), so that an export of
// every record a plant holds keeps one page in memory, not all of them. `next_page` appends
// a page's rows and returns whether more follow; it runs on the request's thread after the
// handler returned. A page that fails, or a server that stops, ends the answer without its
// last chunk: the reader sees an incomplete download, never a short file that looks whole.
void send_csv_pages(httplib::Response& res, const std::string& filename, std::string header,
                    std::function<bool(std::string&)> next_page, const std::atomic<bool>& stopping);

}  // namespace rangex
