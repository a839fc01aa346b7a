set terminal pngcairo size 900,540
set output 'models/pretrained/report_artist_style/loss_skinning.png.amt-tmp'
set title 'Training loss: skinning'
set xlabel 'step'
set ylabel 'loss'
set logscale y
set grid
set key top right
set datafile missing 'NaN'
plot 'models/pretrained/report_artist_style/loss_skinning.dat' using 1:2 with lines lw 1 title 'loss', 'models/pretrained/report_artist_style/loss_skinning.dat' using 1:3 with linespoints pt 7 ps 0.6 title 'val_loss'
unset output
