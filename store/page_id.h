// PageId: a page's number in a store, its index in the "pages" section in the order the pages
// were added (StoreWriter::add_page returns it, StoreReader::read_page takes it). The PageCache
// and its PageSource key pages by the same number.
#pragma once

#include <cstdint>

namespace frontier::store {

using PageId = uint64_t;

}  // namespace frontier::store
