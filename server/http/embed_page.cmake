# Writes OUT, a C++ source defining visloc::server::OperatorPageHtml() as the contents of IN
# (server/http/page/index.html): the page ships inside the server binary.
file(READ ${IN} PAGE)
file(WRITE ${OUT} "// Generated from server/http/page/index.html by server/http/embed_page.cmake.
#include \"server/http/operator_page.h\"

namespace visloc::server {

const std::string& OperatorPageHtml() {
  static const std::string page = R\"visloc_page(${PAGE})visloc_page\";
  return page;
}

}  // namespace visloc::server
")
