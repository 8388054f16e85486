/* Link authentication (target/hil_auth.c): SHA-256 (FIPS 180-2 examples), HMAC-SHA256 (RFC 4231 cases 1, 2
 * and 6), and the trailer: a sealed frame opens once, a replay, an altered byte, the other direction and the
 * 16-bit freshness wrap. */
#include <string.h>

#include "fw_check.h"
#include "hil_auth.h"

static int hex_is(const uint8_t *got, const char *want)
{
    static const char digits[] = "0123456789abcdef";
    size_t i;
    for (i = 0; want[2u * i] != '\0'; i++) {
        if (digits[got[i] >> 4] != want[2u * i] || digits[got[i] & 15u] != want[2u * i + 1u]) {
            return 0;
        }
    }
    return 1;
}

static void sha256_of(const char *msg, size_t n, uint8_t out[32])
{
    hil_sha256_t s;
    hil_sha256_init(&s);
    hil_sha256_update(&s, (const uint8_t *)msg, n);
    hil_sha256_final(&s, out);
}

int main(void)
{
    uint8_t out[32];
    uint8_t key[131];
    sha256_of("abc", 3u, out);
    CHECK(hex_is(out, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"), "sha256(abc)");
    sha256_of("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq", 56u, out);
    CHECK(hex_is(out, "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1"), "sha256(448 bits)");
    {
        hil_sha256_t s;
        uint8_t a[1000];
        int i;
        memset(a, 'a', sizeof a);
        hil_sha256_init(&s);
        for (i = 0; i < 1000; i++) {
            hil_sha256_update(&s, a, sizeof a);
        }
        hil_sha256_final(&s, out);
        CHECK(hex_is(out, "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0"), "sha256(1e6 x a)");
    }
    memset(key, 0x0b, 20u);
    hil_hmac_sha256(key, 20u, (const uint8_t *)"Hi There", 8u, out);
    CHECK(hex_is(out, "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7"), "RFC 4231 case 1");
    hil_hmac_sha256((const uint8_t *)"Jefe", 4u, (const uint8_t *)"what do ya want for nothing?", 28u, out);
    CHECK(hex_is(out, "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"), "RFC 4231 case 2");
    {
        static const char msg[] = "Test Using Larger Than Block-Size Key - Hash Key First";
        memset(key, 0xaa, sizeof key); /* a key longer than a block is hashed first (RFC 2104) */
        hil_hmac_sha256(key, sizeof key, (const uint8_t *)msg, sizeof msg - 1u, out);
        CHECK(hex_is(out, "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54"), "RFC 4231 case 6");
    }
    {
        hil_auth_t host, target;
        uint8_t frame[7 + 8 + HIL_AUTH_TRAILER];
        uint8_t first[sizeof frame];
        const uint8_t ctx[8] = {1, 2, 3, 4, 5, 6, 7, 8};
        int i;
        for (i = 0; i < 32; i++) {
            key[i] = (uint8_t)(i + 1);
        }
        CHECK(hil_auth_init(&host, key, 15u, 0) == -1 && !host.on, "a 15-byte key is refused");
        CHECK(hil_auth_init(&host, key, 32u, 0) == 0 && hil_auth_init(&target, key, 32u, 1) == 0, "init");
        hil_auth_set_context(&host, ctx, sizeof ctx);
        hil_auth_set_context(&target, ctx, sizeof ctx);
        memset(frame, 0x5a, sizeof frame);
        hil_auth_seal(&host, frame, 15u);
        memcpy(first, frame, sizeof frame);
        CHECK(hil_auth_open(&target, frame, sizeof frame) == HIL_AUTH_OK, "a sealed frame opens");
        CHECK(hil_auth_open(&target, frame, sizeof frame) == HIL_AUTH_REPLAYED, "its replay does not");
        frame[9] ^= 1u;
        hil_auth_seal(&host, frame, 15u);
        frame[3] ^= 0x10u;
        CHECK(hil_auth_open(&target, frame, sizeof frame) == HIL_AUTH_FAILED, "an altered frame fails");
        CHECK(hil_auth_open(&host, first, sizeof first) == HIL_AUTH_FAILED, "a frame reflected to its sender fails");
        CHECK(hil_auth_open(&target, frame, 5u) == HIL_AUTH_FAILED, "a frame shorter than the trailer fails");
        for (i = 0; i < 140; i++) { /* 140 x 500 frames: the 16-bit freshness wraps on the way */
            host.tx_fresh += 499u;
            hil_auth_seal(&host, frame, 15u);
            CHECK(hil_auth_open(&target, frame, sizeof frame) == HIL_AUTH_OK, "frame %d after 499 lost", i);
        }
        CHECK(target.rx_fresh == 70002u, "full freshness kept across the wrap: %lu", (unsigned long)target.rx_fresh);
        CHECK(hil_auth_open(&target, first, sizeof first) != HIL_AUTH_OK, "an old frame after the wrap");
    }
    return FW_REPORT("test_auth");
}
