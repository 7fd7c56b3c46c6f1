"""Reads the C3D files our writer made with ezc3d and py-c3d (pip install ezc3d c3d).

Not run by cargo test. First: OSSIFY_PYTHON_CHECK=1 cargo test -p mocap-io --lib python_export
Then: python3 crates/mocap-io/tests/c3d_python_check.py
"""
import os, tempfile, sys, numpy as np, ezc3d, c3d, warnings
D = os.path.join(tempfile.gettempdir(), "ossify-c3d-python-check")
ok=True
for name,M,F,first in [("small",12,50,1),("labels600",600,5,7),("empty",4,0,1)]:
    p=f"{D}/{name}.c3d"
    want=np.loadtxt(f"{D}/{name}.txt",delimiter=",").reshape(F,M,3) if F else np.zeros((0,M,3))
    # ezc3d
    try:
        e=ezc3d.c3d(p)
        pts=e['data']['points']  # 4 x M x F
        P=e['parameters']['POINT']; labels=list(P['LABELS']['value'])
        k=2
        while f'LABELS{k}' in P: labels+=list(P[f'LABELS{k}']['value']); k+=1
        ez=np.transpose(pts[:3],(2,1,0))
        same=np.allclose(np.nan_to_num(ez,nan=1e30),np.nan_to_num(want,nan=1e30),rtol=1e-6,atol=1e-4) if F else True
        print(name,"ezc3d: labels",len(labels),labels[:2],"frames",pts.shape[2],"first",e['header']['points']['first_frame'],"rate",e['header']['points']['frame_rate'],"values equal",same, "nan", int(np.isnan(ez).any(axis=2).sum()), "want nan", int(np.isnan(want).any(axis=2).sum()))
        ok&=same and len(labels)==M and pts.shape[2]==F
    except Exception as ex:
        print(name,"ezc3d FAILED",repr(ex)); ok=False
    try:
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            r=c3d.Reader(open(p,'rb'))  # noqa: SIM115
            frames=[]
            for i,points,analog in r.read_frames():
                xyz=points[:,:3].copy(); xyz[points[:,3]<0]=np.nan
                frames.append(xyz)
        got=np.array(frames).reshape(-1,M,3) if frames else np.zeros((0,M,3))
        same=np.allclose(np.nan_to_num(got.astype(np.float64),nan=1e30),np.nan_to_num(want,nan=1e30),rtol=1e-6,atol=1e-4) if F else True
        pl=list(r.point_labels); k=2
        while r.get(f'POINT:LABELS{k}') is not None: pl+=list(r.get(f'POINT:LABELS{k}').string_array); k+=1
        print(name,"py-c3d: labels",len(pl),"frames",len(frames),"first",r.first_frame,"rate",r.point_rate,"values equal",same,"warnings",[str(x.message)[:80] for x in w])
        ok&=same and len(pl)==M and len(frames)==F
    except Exception as ex:
        print(name,"py-c3d FAILED",repr(ex)); ok=False
print("ALL OK" if ok else "PROBLEMS")
sys.exit(0 if ok else 1)
