import json, statistics as st, sys
old = {(r['scenario'], r['seed']): r for r in json.load(open('/work/main/benches/results/paper_full_level.json'))['rows']}
new = {(r['scenario'], r['seed']): r for r in json.load(open(sys.argv[1]))['rows']}
for sc in ['test1', 'test2', 'test3', 'urban']:
    ks = sorted(k for k in new if k[0] == sc)
    if not ks: continue
    f = lambda d, m, key: [d[k][m][key] for k in ks]
    o, n = f(old, 'sar-min+af', 'reflector_error_max_cm'), f(new, 'sar-min+af', 'reflector_error_max_cm')
    wo, wn = sum(f(old, 'sar-min+af', 'within_2cm_1db')), sum(f(new, 'sar-min+af', 'within_2cm_1db'))
    po, pn = max(f(old, 'sar-min+af', 'peak_loss_max_db')), max(f(new, 'sar-min+af', 'peak_loss_max_db'))
    ro, rn = max(f(old, 'sar-min+af', 'rpe_1m_across_mm')), max(f(new, 'sar-min+af', 'rpe_1m_across_mm'))
    fo = [old[k]['entropy_far']['vs_truth_pct']['sar-min+af'] for k in ks]; fn = [new[k]['entropy_far']['vs_truth_pct']['sar-min+af'] for k in ks]
    so = [old[k]['af_track_scale_pct'] + 0 for k in ks]
    print(f"{sc} ({len(ks)}): af median {st.median(o):.2f} -> {st.median(n):.2f}, max {max(o):.2f} -> {max(n):.2f}; within {wo} -> {wn}; peak {po:+.2f} -> {pn:+.2f} dB; rpe {ro:.2f} -> {rn:.2f}; far median {st.median(fo):+.2f} -> {st.median(fn):+.2f}, within 0.2: {sum(abs(x)<=0.2 for x in fo)} -> {sum(abs(x)<=0.2 for x in fn)}")
    for k in ks:
        a, b = old[k]['sar-min+af'], new[k]['sar-min+af']
        print(f"   s{k[1]}: {a['reflector_error_max_cm']:.2f} -> {b['reflector_error_max_cm']:.2f} cm, {a['peak_loss_max_db']:+.2f} -> {b['peak_loss_max_db']:+.2f} dB, scale {old[k]['af_track_scale_pct']:+.4f} -> {new[k]['af_track_scale_pct']:+.4f} (track {new[k]['sarmin_track_scale_pct']:+.4f}), far {old[k]['entropy_far']['vs_truth_pct']['sar-min+af']:+.2f} -> {new[k]['entropy_far']['vs_truth_pct']['sar-min+af']:+.2f}")
