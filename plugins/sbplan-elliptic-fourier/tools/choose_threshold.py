"""How default_threshold was chosen: re-rasterized copies of every registered candidate symbol.

Each symbol is drawn 6 times (random size 40-100 px, random rotation, 4x supersampled then area-averaged),
extracted with the opencv extractor, approximated with douglas-peucker, and described. Prints the
distances between copies of one shape ('same') and between different shapes ('diff').
Run: python3 plugins/sbplan-elliptic-fourier/tools/choose_threshold.py (seeded, deterministic).
"""
import pathlib
import sys

import cv2
import numpy as np

# run from a checkout without installing the plugin
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from sbplan import registry as plugins
from sbplan_elliptic_fourier import EllipticFourierMatcher
from sbplan.synth import symbol_outline
ext=plugins.extractor('opencv'); apx=plugins.approximator('douglas-peucker')
names=plugins.symbol_names()
rng=np.random.default_rng(0)
def raster(rings,size,ang):
    W=int(size*1.6)+10; img=np.zeros((W*4,W*4),np.uint8)
    c,s=np.cos(ang),np.sin(ang)
    R=np.array([[c,-s],[s,c]])
    polys=[(((r-0.5)@R.T)*size+W/2)*4 for r in rings]
    cv2.fillPoly(img,[np.round(polys[0]).astype(np.int32)],255)
    for h in polys[1:]: cv2.fillPoly(img,[np.round(h).astype(np.int32)],0)
    img=cv2.resize(img,(W,W),interpolation=cv2.INTER_AREA)
    cs=[c for c in ext.extract(img>127) if not c.is_hole]
    c=max(cs,key=len)
    return apx.approximate(c)
shapes={}
for n in names:
    rings=symbol_outline(n)
    shapes[n]=[raster(rings,rng.uniform(40,100),rng.uniform(0,2*np.pi)) for _ in range(6)]
for mname,m in [("elliptic-fourier",EllipticFourierMatcher()),("fourier",plugins.matcher("fourier"))]:
    D={n:m.describe_many(v) for n,v in shapes.items()}
    same=[];diff=[]
    for n in names:
        d=m.distance_matrix(D[n],D[n]); same.append(d[np.triu_indices(6,1)])
        for k in names:
            if k>n: diff.append(m.distance_matrix(D[n],D[k]).ravel())
    same=np.concatenate(same); diff=np.concatenate(diff)
    per={n:m.distance_matrix(D[n],D[n]).max() for n in names}
    print(mname, 'same q50 q95 q99 max',np.percentile(same,[50,95,99]).round(3),same.max().round(3),'diff q1 q5 q50',np.percentile(diff,[1,5,50]).round(3))
    thr=m.default_threshold
    for t in (0.1, thr):
        print('  at',t,': same below',(same<t).mean().round(3),'diff above',(diff>=t).mean().round(3))
    print('  worst same', sorted(per.items(), key=lambda x:-x[1])[:5])
