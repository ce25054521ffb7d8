// StorePageSource: the PageSource over a StoreReader, so the cache pages in store pages by id.
// Thread-safe because StoreReader::read_page is. The reader must outlive the source.
#pragma once

#include "store/page_cache.h"
#include "store/store_file.h"

namespace frontier::store {

class StorePageSource : public PageSource {
 public:
  explicit StorePageSource(const StoreReader& reader) : reader_(reader) {}
  Result<PageData> load(PageId id) override {
    auto page = reader_.read_page(id);
    if (!page) return page.status();
    return PageData{page->codec, std::move(page->payload)};
  }

 private:
  const StoreReader& reader_;
};

}  // namespace frontier::store
