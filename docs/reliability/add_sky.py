#!/usr/bin/env python3
# usage: add_sky.py IN OUT K: a copy of the cell image IN with K x its NOISESIG added to HDU 0 (BITPIX -32 or -64)
import sys, numpy as np
src, dst, k = sys.argv[1], sys.argv[2], float(sys.argv[3])
b = bytearray(open(src,'rb').read())
cards = {}
i = 0
while True:
    card = b[i:i+80].decode()
    key = card[:8].strip()
    if key == 'END': break
    if card[8:10] == '= ': cards[key] = card[10:].split('/')[0].strip()
    i += 80
hdr_end = ((i + 80 + 2879)//2880)*2880
nx, ny, bp = int(cards['NAXIS1']), int(cards['NAXIS2']), int(cards['BITPIX'])
sig = float(cards['NOISESIG'])
dt = {-32: '>f4', -64: '>f8'}[bp]
n = nx*ny*abs(bp)//8
a = np.frombuffer(bytes(b[hdr_end:hdr_end+n]), dtype=dt).copy()
a += k*sig
b[hdr_end:hdr_end+n] = a.astype(dt).tobytes()
open(dst,'wb').write(b)
print(sig)
