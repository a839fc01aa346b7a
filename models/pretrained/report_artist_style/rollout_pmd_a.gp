set terminal pngcairo size 900,540
set output 'models/pretrained/report_artist_style/rollout_pmd_a.png.amt-tmp'
set title 'PMD_a over rollout frames'
set xlabel 'frame'
set ylabel 'PMD_a (cm)'
set grid
set key top left
set datafile missing 'NaN'
plot 'models/pretrained/report_artist_style/rollout_0.dat' using 1:2 with lines lw 2 title 'Apparel module, GT mask + weights, held-out characters, artist-style', 'models/pretrained/report_artist_style/rollout_1.dat' using 1:2 with lines lw 2 title 'Body + apparel modules, held-out characters, artist-style', 'models/pretrained/report_artist_style/rollout_2.dat' using 1:2 with lines lw 2 title 'Full model, held-out characters, artist-style', 'models/pretrained/report_artist_style/rollout_3.dat' using 1:2 with lines lw 2 title 'hold offset rule (no network), held-out characters, artist-style', 'models/pretrained/report_artist_style/rollout_4.dat' using 1:2 with lines lw 2 title 'Skinning baseline (LBS, GT body weights), held-out characters, artist-style'
unset output
