#pragma once
// The operator's page (page/index.html), built into the server at compile time: one
// hand-written file of HTML, CSS and JavaScript, no library and nothing fetched from elsewhere.

#include <string>

namespace visloc::server {

const std::string& OperatorPageHtml();

}  // namespace visloc::server
